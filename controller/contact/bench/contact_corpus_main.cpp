// poise-contact-corpus: writes the benchmark corpus (fixed seed) to a text file.
#include <cstdio>
#include <exception>
#include <string>

#include <CLI/CLI.hpp>

#include "contact_corpus.hpp"
#include "poise/cli/parse.hpp"

int main(int argc, char** argv) {
  CLI::App app{
      "Write a corpus of random contact problems (feasible and infeasible, single and "
      "double support, feet tilted up to 10 deg) for poise-bench-contact."};
  std::string out;
  int count = 10000;
  unsigned seed = 20240601;
  app.add_option("output", out, "output file")->required();
  app.add_option("--count", count, "number of problems")->check(CLI::PositiveNumber);
  app.add_option("--seed", seed, "random seed");
  POISE_CLI_PARSE(app, argc, argv);
  try {
    poise::contact::bench::write_corpus(out, poise::contact::bench::generate_corpus(count, seed));
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-contact-corpus: error: %s\n", e.what());
    return 1;
  }
  std::printf("wrote %d problems (seed %u) to %s\n", count, seed, out.c_str());
  return 0;
}
