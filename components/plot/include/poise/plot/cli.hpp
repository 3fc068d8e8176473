#pragma once
// The verbs of the `poise` tool in this module: `poise export FILE --csv` and `poise plot FILE`.
//
// Exit status of both: 0 all done; 1 output written but something was wrong (a message that does
// not decode, a file cut short or damaged, gnuplot failed); 2 nothing written (bad arguments, not
// an MCAP file, a topic the file does not hold, gnuplot missing, output not writable).

namespace poise::plot {

int export_main(int argc, char** argv);
int plot_main(int argc, char** argv);

}  // namespace poise::plot
