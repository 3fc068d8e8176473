#pragma once
// The distributed launcher and the push verb.

namespace poise::launch {

/// `poise run SCENARIO` (distributed mode): starts poise-sim, poise-estimator, poise-contact and
/// poise-controller as separate processes on a fresh loopback DDS domain, runs the scenario
/// (lockstep by default, --realtime for wall-clock time), prints progress and a one-line verdict,
/// writes the JSON result (--output, default results/<scenario>.json). Every child is bounded in
/// time and killed by pid on exit, on Ctrl-C and when any child fails (which is then named, with
/// its last stderr lines). Returns 0 when the robot survived, 1 when it did not, 2 on errors.
/// argv[0] is the program name as shown in --help.
int run_distributed(int argc, char** argv);

/// `poise push --link L --force FX FY FZ [--point X Y Z] [--duration S] [--start T]`: publishes
/// one Disturbance (PUSH) on poise/disturbance and waits until a subscriber matched.
int push_main(int argc, char** argv);
/// `poise estop [--release]`: the robot's e-stop on poise/estop.
int estop_main(int argc, char** argv);

/// `poise launch DEPLOYMENT.yaml [--host NAME] [--check]`: starts this machine's share of a
/// deployment file (deployment.hpp) and supervises it: generated per-host DDS files, CPU affinity
/// and SCHED_FIFO priority per component, restart policies, children that die with the launcher,
/// a JSON result (also when it fails). 0: done (the simulator's robot survived), 1: it fell,
/// 2: a failure (named).
int launch_main(int argc, char** argv);

/// `poise security init DIR`: CA, identities and signed governance / permissions documents for
/// DDS Security (security_cli.cpp).
int security_main(int argc, char** argv);

}  // namespace poise::launch
