#pragma once
// The estimator's accuracy measured from the wire (issue #20 item 2): a distributed run of a
// scenario (`poise run SCENARIO --record FILE`, real processes over loopback DDS), then
// poise/state against poise/ground_truth of the recording, matched by tick.
//
// Figures (ticks flagged STATE_INITIALIZING left out: the first 0.5 s; a run in which the robot
// falls is evaluated up to its first non-foot contact):
//  - world frame: base position, base velocity, CoM position and velocity errors (norm of the
//    difference), attitude error (angle of R_est^T R_true) and tilt error (angle between the
//    estimated and true base z axes: roll/pitch, yaw excluded);
//  - relative to the supporting feet: the CoM and the base position and velocity minus the mean
//    position and velocity of the feet in contact (the truth's contact flags choose the feet for
//    both sides), estimated minus true. The true feet come from the true base pose and the
//    encoders' q carried in poise/state (the ground truth has no foot poses), their velocities
//    from central differences over +-5 ticks (not from the encoders' filtered qd);
//  - drift: the world base and CoM position errors at 5, 10 and 20 s (NaN past the run's end).
// Used by poise-bench-estimator-wire and tests/estimator/estimator_wire_test.cpp.

#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace poise::estimator_bench {

/// RMS and maximum of a series of non-negative errors.
struct Stat {
  double rms = 0.0;
  double max = 0.0;
  std::uint64_t n = 0;
  double sum_sq = 0.0;
  void add(double e) {
    sum_sq += e * e;
    if (e > max) max = e;
    ++n;
    rms = std::sqrt(sum_sq / static_cast<double>(n));
  }
};

struct Accuracy {
  std::string scenario, estimator;
  double duration_s = 0.0;         ///< time of the last matched tick
  std::uint64_t matched_ticks = 0;  ///< ticks with both topics (and past initialisation)
  std::uint64_t state_ticks = 0, truth_ticks = 0;
  // World frame [m, m/s, deg].
  Stat base_pos, base_vel, com_pos, com_vel, attitude_deg, tilt_deg;
  Stat base_pos_early;  ///< base position error before t = 2 s (the platforms stand still)
  // Relative to the supporting feet [m, m/s].
  Stat rel_com_pos, rel_com_vel, rel_base_pos, rel_base_vel;
  std::uint64_t no_support_ticks = 0;  ///< ticks with no foot in contact (truth): no relative figure
  /// Time of the first tick with a non-foot contact (the robot fell): the figures stop there.
  /// NaN: it did not fall.
  double fell_at_s = std::numeric_limits<double>::quiet_NaN();
  // World drift: base / CoM position error at 5, 10, 20 s [m] (NaN past the end).
  double drift_t[3] = {5.0, 10.0, 20.0};
  double base_drift[3] = {0.0, 0.0, 0.0};
  double com_drift[3] = {0.0, 0.0, 0.0};
  bool ran = false;       ///< made by run_and_analyse (else: a recording analysed)
  bool survived = false;  ///< the run's verdict (poise run's exit status 0)
  std::string error;      ///< "" or why there are no figures
};

/// Reads a recording of a run of `scenario_file` (its robot configuration builds the model).
Accuracy analyse_recording(const std::string& mcap, const std::string& scenario_file);

struct RunOptions {
  std::string poise_bin;      ///< path of build/bin/poise
  std::string scenario;       ///< scenario file or name
  std::string estimator;      ///< "invariant-ekf" | "leg-odometry" ("": the scenario's)
  double duration = -1.0;     ///< override [s] (<= 0: the scenario's)
  int domain = -1;            ///< DDS domain (-1: poise run claims a free one)
  std::string dir;            ///< output directory (recording, result JSON, logs)
  double timeout_s = 600.0;   ///< wall-clock bound of the run (then killed by pid)
  std::vector<std::string> extra;  ///< more poise run options
};

/// Runs `poise run SCENARIO --record DIR/NAME.mcap` (bounded in time, killed by pid on timeout),
/// then analyse_recording(). `error` says what failed (run, timeout, recording).
Accuracy run_and_analyse(const RunOptions& options);

/// Human-readable table (one block per result).
std::string format_table(const std::vector<Accuracy>& results);
/// JSON array of the results.
std::string to_json(const std::vector<Accuracy>& results);

}  // namespace poise::estimator_bench
