#pragma once
// `poise reference play FILE` (also the executable poise-reference): plays a balance-reference
// trajectory (trajectory.hpp) on poise/balance_reference in step with poise/state. On the state
// of tick k it sends the references of ticks k+1 .. k + lead (header.tick = the tick each is
// for, stamp = its robot time); poise-controller holds them and applies each at its tick, so a
// played trajectory is applied tick-exactly in lockstep and in real time alike (a reference that
// arrives after its tick is counted by the controller as late).

namespace poise::reference {

/// `poise reference play ...` (argv[0] is the program name, argv[1] the file). Exit codes: 0 the
/// trajectory was played to its end, 2 bad arguments or setup failure, 3 interrupted first.
int play_main(int argc, char** argv);

/// The `poise reference` verb: `poise reference play ...` runs the poise-reference executable
/// beside the `poise` tool (exec, same arguments), so that the tool does not link the node
/// runtime (src/cli.cpp).
int cli_main(int argc, char** argv);

}  // namespace poise::reference
