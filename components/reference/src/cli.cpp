// The `poise reference` verb: `poise reference play FILE ...` execs poise-reference (same folder
// as the running `poise`) with the arguments after `play`.
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

#include "poise/reference/play.hpp"

namespace poise::reference {

int cli_main(int argc, char** argv) {
  const bool help = argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h";
  if (help || std::string(argv[1]) != "play") {
    std::fprintf(help ? stdout : stderr,
                 "usage: poise reference play FILE [options]   (poise reference play --help)\n"
                 "Plays a balance-reference trajectory (deploy/scenarios/references/) on\n"
                 "poise/balance_reference in step with poise/state; poise-controller applies\n"
                 "each reference at its tick.\n");
    return help ? 0 : 2;
  }
  std::error_code ec;
  const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
  const std::string exe =
      ((ec ? std::filesystem::path(".") : self.parent_path()) / "poise-reference").string();
  std::vector<std::string> args{exe};
  for (int i = 2; i < argc; ++i)
    args.emplace_back(argv[i]);
  std::vector<char*> c_args;
  for (auto& a : args)
    c_args.push_back(a.data());
  c_args.push_back(nullptr);
  ::execv(exe.c_str(), c_args.data());
  std::fprintf(stderr, "poise reference: cannot run %s: %s\n", exe.c_str(), std::strerror(errno));
  return 2;
}

}  // namespace poise::reference
