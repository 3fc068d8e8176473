// poise-launch SCENARIO ...: the distributed `poise run` as a standalone program.
#include <string>

#include "poise/launch/launch.hpp"

int main(int argc, char** argv) {
  std::string name = "poise-launch";
  argv[0] = name.data();
  return poise::launch::run_distributed(argc, argv);
}
