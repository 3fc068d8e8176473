// poise-reference: `poise reference play` as a standalone executable (tests, scripts).
#include "poise/reference/play.hpp"

int main(int argc, char** argv) {
  return poise::reference::play_main(argc, argv);
}
