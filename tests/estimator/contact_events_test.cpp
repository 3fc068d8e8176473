// Contact detection delays against the simulator's truth (#20 item 3), closed loop in process
// with the industrial sensor defaults (simulator/sim/SENSORS.md) and the detector's light-touch
// rule on (contact_ft_noise 0.5 N, the default F/T's noise and the default): the estimator's
// contact flags drive the controller. Scenarios in which contacts change: a drop onto the feet, a
// lateral push that lifts a foot, a step in place (deploy/scenarios/step_in_place.yaml: its balance
// reference swings the right foot 3 cm up and down, played by the in-process loop).
//
// Truth events: transitions of GroundTruth in_contact that then hold for 10 ticks (contact
// bounces at an impact are one event). Each is matched with the estimate's nearest transition
// of the same kind within 100 ms; delay = estimated tick - the tick of the true change of that
// kind nearest to it among the event and the bounces of the 20 ticks before it (a foot that taps
// the ground before it settles touches down several times; negative: early).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include "poise/inprocess/in_process_loop.hpp"
#include "poise/model/robot_config.hpp"
#include "poise/scenario/scenario.hpp"

namespace poise::inprocess {
namespace {

struct Event {
  long tick = 0;
  bool touch_down = false;
};

struct FootLog {
  std::vector<std::uint8_t> truth, est;
  /// The flag's documented meaning on the truth (idl/README.md "Contact flags"): in contact and
  /// carrying more than 1 % of the weight along the sole normal.
  std::vector<std::uint8_t> truth_loaded;
};

/// A true event and what was flagged for it.
struct Matched {
  long true_tick = 0;
  bool touch_down = false;
  bool matched = false;
  double delay_ms = 0.0;  ///< when matched
};

/// POISE_CONTACT_EVENTS_CSV=DIR: one row per tick and foot into DIR/<scenario>.csv (tick, side,
/// true contact, estimated contact, measured normal force, true normal force, true sole centre
/// height, planned foot mode, estimated sole height, true foot x and y, true and estimated height
/// of the sole rectangle's lowest corner), to look at what the flags follow.
std::FILE* open_csv(std::string file) {
  if (const char* seed = std::getenv("POISE_CONTACT_EVENTS_SEED")) file += std::string("_") + seed;
  const char* dir = std::getenv("POISE_CONTACT_EVENTS_CSV");
  if (dir == nullptr || *dir == 0) return nullptr;
  std::FILE* out = std::fopen((std::string(dir) + "/" + file + ".csv").c_str(), "w");
  if (out)
    std::fprintf(out,
                 "tick,side,truth,est,fn_meas,fn_true,foot_z_true,mode,foot_z_est,foot_x_true,foot_"
                 "y_true,c0_true,c1_true,c2_true,c3_true,c0_est,c1_est,c2_est,c3_est\n");
  return out;
}

/// Heights in W of the corners of a sole rectangle, the foot frame at (R, p).
std::array<double, 4> corner_z(const model::SoleRectangle& s, const Eigen::Matrix3d& R,
                               const Eigen::Vector3d& p) {
  std::array<double, 4> z{};
  int i = 0;
  for (double x : {s.x_min, s.x_max})
    for (double y : {s.y_min, s.y_max})
      z[static_cast<std::size_t>(i++)] = (p + R * Eigen::Vector3d(x, y, -s.height)).z();
  return z;
}

/// Debounced transitions of a per-tick contact signal.
std::vector<Event> events(const std::vector<std::uint8_t>& s, int hold) {
  std::vector<Event> out;
  std::uint8_t state = s.empty() ? 0 : s[0];
  for (std::size_t k = 1; k < s.size(); ++k) {
    if (s[k] == state) continue;
    bool holds = true;
    for (std::size_t j = k; j < std::min(s.size(), k + static_cast<std::size_t>(hold)); ++j)
      holds = holds && s[j] == s[k];
    if (!holds) continue;
    state = s[k];
    out.push_back(Event{static_cast<long>(k), state != 0});
  }
  return out;
}

int transitions(const std::vector<std::uint8_t>& s) {
  int n = 0;
  for (std::size_t k = 1; k < s.size(); ++k)
    n += s[k] != s[k - 1];
  return n;
}

struct Result {
  std::vector<double> touch_down_ms, lift_off_ms;
  int unmatched = 0;
  int truth_transitions = 0;         ///< debounced (events)
  int truth_raw_transitions = 0;     ///< every change of the true flag (bounces included)
  int truth_loaded_transitions = 0;  ///< every change of FootLog::truth_loaded
  int est_transitions = 0;
  /// The longest a flag stayed on while the true foot touched nothing [ms] (either foot).
  double longest_flag_in_air_ms = 0.0;
  bool survived = false;
  double foot_slip_max_m = 0.0;  ///< the verdict's (the feet's largest true slide)
  std::vector<Matched> all;      ///< every true event of both feet
  /// Every event of both feet in the flags' documented meaning (FootLog::truth_loaded).
  std::vector<Matched> loaded;
  int loaded_unmatched = 0;
  long swing_start = -1;  ///< first tick at which the reference planned a swing (-1: never)
};

/// Matches the debounced events of one foot's true signal (raw contact, or the flags' documented
/// meaning) with the estimate's changes; appends one Matched per true event and returns how many.
int match(const std::vector<std::uint8_t>& truth, const std::vector<std::uint8_t>& est, int side,
          const char* kind, double ms, std::vector<Matched>& out) {
  const auto te = events(truth, 10);
  const auto ee = events(est, 1);
  // Every raw change of the truth (bounces included): a foot that taps the ground before it
  // settles makes several true touch-downs, and the estimate may follow each of them.
  const auto raw = events(truth, 1);
  for (const Event& t : te) {
    long best = 1000000;
    for (const Event& e : ee)
      if (e.touch_down == t.touch_down && std::abs(e.tick - t.tick) < std::abs(best))
        best = e.tick - t.tick;
    if (std::abs(best) > 100) {
      out.push_back(Matched{t.tick, t.touch_down, false, 0.0});
      std::printf("  unmatched %s %s of foot %d at tick %ld\n", kind,
                  t.touch_down ? "touch-down" : "lift-off", side, t.tick);
      continue;
    }
    // The delay of that estimated change against the true change of the same kind nearest to
    // it within the settling (the debounced event and up to 2 x 10 ticks of bounces before it).
    const long est_tick = t.tick + best;
    long delay = best;
    for (const Event& e : raw)
      if (e.touch_down == t.touch_down && e.tick <= t.tick && e.tick >= t.tick - 20 &&
          std::abs(est_tick - e.tick) < std::abs(delay))
        delay = est_tick - e.tick;
    out.push_back(Matched{t.tick, t.touch_down, true, static_cast<double>(delay) * ms});
    std::printf("  %-6s %-10s of foot %d at tick %5ld: %+.0f ms\n", kind,
                t.touch_down ? "touch-down" : "lift-off", side, t.tick,
                static_cast<double>(delay) * ms);
  }
  return static_cast<int>(te.size());
}

using Reference = std::function<void(InProcessLoop&, double)>;

/// controller_file: a controller YAML for the run (empty: the defaults;
/// POISE_CONTACT_EVENTS_CONTROLLER=FILE another one for every run); ground_friction: the ground's
/// Coulomb coefficient (NaN: the scenario's); edit: changes to the scenario, applied last (they
/// win over the POISE_CONTACT_EVENTS_* variables).
Result run(const std::string& file, double duration, const Reference& reference = {},
           double push_scale = 1.0, std::uint64_t seed = 0, const std::string& controller_file = {},
           double ground_friction = std::numeric_limits<double>::quiet_NaN(),
           const std::function<void(scenario::Scenario&)>& edit = {}) {
  scenario::Scenario sc =
      scenario::load_scenario(std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/" + file);
  for (sim::Push& p : sc.sim.pushes)
    p.force_W *= push_scale;
  if (seed != 0) sc.sim.imu.seed = seed;
  if (std::isfinite(ground_friction)) sc.sim.world.ground.friction = ground_friction;
  // The detector's light-touch rule (EstimatorConfig::contact_ft_noise, 0.5 N by default): the
  // default F/T's noise; POISE_CONTACT_EVENTS_FT_NOISE=N another value (0: off).
  const char* ft_noise = std::getenv("POISE_CONTACT_EVENTS_FT_NOISE");
  sc.estimator.contact_ft_noise = ft_noise ? std::atof(ft_noise) : 0.5;
  // POISE_CONTACT_EVENTS_REST_TIME=S: the detector's resting rule (scenario
  // estimator.contact_rest_time).
  if (const char* rest = std::getenv("POISE_CONTACT_EVENTS_REST_TIME"))
    sc.estimator.contact_rest_time = std::atof(rest);
  if (edit) edit(sc);
  LoopOptions opt;
  opt.duration = duration;
  opt.controller_config_file = controller_file;
  if (const char* c = std::getenv("POISE_CONTACT_EVENTS_CONTROLLER"))
    opt.controller_config_file = c;
  InProcessLoop loop(sc, opt);
  const double weight =
      loop.controller().model().total_mass * loop.controller().model().gravity.norm();
  const model::RobotConfig rc = model::load_robot_config(sc.robot_config);
  std::array<int, 2> sim_foot{-1, -1};
  for (int side = 0; side < 2; ++side)
    for (std::size_t f = 0; f < sc.sim.robot.feet.size(); ++f)
      if (sc.sim.robot.feet[f].frame == rc.feet[side].frame) sim_foot[side] = static_cast<int>(f);
  std::array<FootLog, 2> log;
  long swing_start = -1;
  std::FILE* csv = open_csv(file);
  const int steps = static_cast<int>(std::lround(duration / loop.simulator().dt()));
  for (int k = 0; k < steps; ++k) {
    if (reference) reference(loop, loop.time());
    std::array<std::uint8_t, 2> truth{};
    std::array<double, 2> fn_true{}, z_true{}, x_true{}, y_true{};
    std::array<std::array<double, 4>, 2> corner_true{};
    for (int side = 0; side < 2; ++side) {
      const auto& tf = loop.truth().feet[static_cast<std::size_t>(sim_foot[side])];
      truth[side] = tf.in_contact;
      fn_true[side] = (tf.X_WF.linear().transpose() * tf.force_W).z();
      z_true[side] = tf.X_WF.translation().z();
      x_true[side] = tf.X_WF.translation().x();
      y_true[side] = tf.X_WF.translation().y();
      corner_true[side] = corner_z(rc.feet[side].sole, tf.X_WF.linear(), tf.X_WF.translation());
    }
    loop.step();  // the state of this tick (from this tick's sensors), then the step
    for (int side = 0; side < 2; ++side)
      if (swing_start < 0 && loop.reference().feet[side].mode == controller::FootMode::kSwing)
        swing_start = k;
    for (int side = 0; side < 2; ++side) {
      log[side].truth.push_back(truth[side]);
      log[side].truth_loaded.push_back(truth[side] && fn_true[side] > 0.01 * weight ? 1 : 0);
      log[side].est.push_back(loop.state().feet[side].in_contact);
      if (csv)
        std::fprintf(csv, "%d,%d,%d,%d,%.3f,%.3f,%.5f,%d,%.5f,%.5f,%.5f", k, side, truth[side],
                     loop.state().feet[side].in_contact ? 1 : 0,
                     loop.state().feet[side].normal_force, fn_true[side], z_true[side],
                     static_cast<int>(loop.reference().feet[side].mode),
                     loop.state().feet[side].X_WF.p.z(), x_true[side], y_true[side]);
      if (csv) {
        const auto& X = loop.state().feet[side].X_WF;
        for (double z : corner_true[side])
          std::fprintf(csv, ",%.7f", z);
        for (double z : corner_z(rc.feet[side].sole, X.R, X.p))
          std::fprintf(csv, ",%.7f", z);
        std::fprintf(csv, "\n");
      }
    }
  }
  if (csv) std::fclose(csv);
  Result r;
  r.swing_start = swing_start;
  const RunResult lr = loop.result();
  r.survived = lr.survived;
  r.foot_slip_max_m = lr.foot_slip_max_m;
  std::printf(
      "  verdict: CoM error max %.3f m, foot slip max %.3f m, non-foot contact ticks %d, "
      "base height min %.3f m\n",
      lr.com_error_max_m, lr.foot_slip_max_m, lr.non_foot_contacts, lr.min_base_height_m);
  const double ms = loop.simulator().dt() * 1e3;
  for (int side = 0; side < 2; ++side) {
    r.est_transitions += transitions(log[side].est);
    long in_air = 0;
    for (std::size_t k = 0; k < log[side].est.size(); ++k) {
      in_air = log[side].est[k] && !log[side].truth[k] ? in_air + 1 : 0;
      r.longest_flag_in_air_ms = std::max(
          r.longest_flag_in_air_ms, static_cast<double>(in_air) * loop.simulator().dt() * 1e3);
    }
    r.truth_raw_transitions += transitions(log[side].truth);
    r.truth_loaded_transitions += transitions(log[side].truth_loaded);
    if (std::getenv("POISE_CONTACT_EVENTS_TRACE"))
      for (std::size_t k = 1; k < log[side].est.size(); ++k)
        if (log[side].est[k] != log[side].est[k - 1] ||
            log[side].truth[k] != log[side].truth[k - 1] ||
            log[side].truth_loaded[k] != log[side].truth_loaded[k - 1])
          std::printf("  foot %d tick %zu truth %d loaded %d estimate %d\n", side, k,
                      log[side].truth[k], log[side].truth_loaded[k], log[side].est[k]);
    r.truth_transitions += match(log[side].truth, log[side].est, side, "true", ms, r.all);
    match(log[side].truth_loaded, log[side].est, side, "loaded", ms, r.loaded);
  }
  for (const Matched& m : r.all)
    if (m.matched)
      (m.touch_down ? r.touch_down_ms : r.lift_off_ms).push_back(m.delay_ms);
    else
      ++r.unmatched;
  for (const Matched& m : r.loaded)
    if (!m.matched) ++r.loaded_unmatched;
  std::printf(
      "%-32s survived %d | truth events %d (raw changes %d, loaded > 1 %% W changes %d), "
      "estimate changes %d, unmatched %d, longest flag on in the air %.0f ms\n",
      file.c_str(), r.survived, r.truth_transitions, r.truth_raw_transitions,
      r.truth_loaded_transitions, r.est_transitions, r.unmatched, r.longest_flag_in_air_ms);
  return r;
}

void expect_delays_within(const Result& r, double early_ms, double late_ms) {
  for (double d : r.touch_down_ms) {
    EXPECT_LE(d, late_ms);
    EXPECT_GE(d, -early_ms);
  }
  for (double d : r.lift_off_ms) {
    EXPECT_LE(d, late_ms);
    EXPECT_GE(d, -early_ms);
  }
  EXPECT_EQ(r.unmatched, 0);
}

// No chatter: the flags change no more often than the truth. The truth in either sense: the
// simulator's raw flag (any contact point: an edge grazing the ground with 0.5 N counts), or the
// flags' documented meaning (carrying more than 1 % of the weight). A landing that bounces on
// one edge (lateral_push_unloads_foot at commit 156a37c: 199 N, then 0.5 N for 3 ticks with the
// sole rising, then 17 N) changes the second and not the first.
int chatter_bound(const Result& r) {
  return std::max(r.truth_raw_transitions, r.truth_loaded_transitions);
}

// A flag on a foot in the air makes it a support for the controller: it may stay on after a
// true lift-off only as long as a lift-off is flagged late (the 5 ms target, +6 ms measured over
// the step's noise seeds), with margin. A rocking foot taken to rest kept it 110-113 ms.
void expect_no_flag_long_in_the_air(const Result& r) {
  EXPECT_LE(r.longest_flag_in_air_ms, 10.0);
}

TEST(ContactEvents, DropOntoTheFeet) {
  const Result r = run("drop_onto_feet.yaml", 1.5);
  EXPECT_TRUE(r.survived);
  EXPECT_EQ(r.touch_down_ms.size(), 2u);  // each foot lands once (bounces are one event)
  expect_delays_within(r, 5.0, 5.0);
  // No chatter: the flags change no more often than the truth, whose impact bounces (a few ms
  // off the ground) they follow.
  EXPECT_LE(r.est_transitions, chatter_bound(r));
  expect_no_flag_long_in_the_air(r);
}

TEST(ContactEvents, LateralPushLiftsAFoot) {
  const Result r = run("lateral_push_unloads_foot.yaml", 3.0);
  EXPECT_TRUE(r.survived);
  EXPECT_GE(r.lift_off_ms.size(), 1u);  // the push lifts a foot
  EXPECT_GE(r.touch_down_ms.size(), 1u);
  expect_delays_within(r, 5.0, 5.0);
  EXPECT_LE(r.est_transitions, chatter_bound(r));
  expect_no_flag_long_in_the_air(r);
}

TEST(ContactEvents, StepInPlace) {
  // The controller of 2026-12-04 (config/ankle_first.yaml: the defaults then, the trunk's pitch
  // left as (10) leaves it), on which this run's events were characterised: with the defaults
  // since 2026-12-05 (the trunk's pitch brought back) the weight leaves the right foot more
  // gently, and its load fades below 1 % of W ~0.1 s before the swing lifts it, with no
  // separation before the swing (StepInPlaceWithTheDefaults; idl/README.md "Contact flags").
  // The weight goes over the left foot, then the reference swings the right foot (FOOT_SWING,
  // the contact detector's prior: contact_detector.hpp) and sets it down. Before the swing the
  // right foot, with the weight gone, leaves the ground by 0.3 mm (tick 3226, seed 1; 3261 with
  // the ankle-first controller defaults since 2026-12-04) and comes back down with 2 N (0.4 % of
  // the weight, tick 3439; 3468) 0.1 s before its load grows past 1 %:
  // that light touch-down is flagged from the step it makes in the F/T reading (the detector's
  // light-touch rule, on here; without it +91 ms, unmatched). Every
  // true event of the run, the swing's lift-off and the landing included, is checked against
  // the 5 ms target, on seed 1; other seeds: the DISABLED_ measurement below and idl/README.md
  // "Contact flags". The resting rule off (the estimator's default until 2026-12-05, the flag
  // meaning "loaded"): with it on, this controller's 0.3 mm roll-off before the swing, a foot
  // resting with 2-8 N that peels off about an edge, is flagged +30 ms (the estimated corners
  // follow the true ones within ~20 um only, the F/T reads its 1.7 N offset at zero load:
  // idl/README.md "The landing rule").
  const Result r =
      run("step_in_place.yaml", 8.0, {}, 1.0, 0,
          std::string(POISE_SOURCE_DIR) + "/controller/momentum/config/ankle_first.yaml",
          std::numeric_limits<double>::quiet_NaN(), [](scenario::Scenario& sc) {
            sc.estimator.contact_rest_time = 0.0;
            // The trajectory characterised above is the contact solver's at a residual of 1e-9.
            // The 0.3 mm roll-off of a foot resting with 2 N is a knife edge: at 1e-10 the true
            // separation moves so that the flag leads it by 8 ms, at 1e-7 (the default) by 13 ms
            // (ticks 3260 / 3270 against 3226). This test checks the detector on that one
            // trajectory; StepInPlaceWithTheDefaults checks the run as it is today.
            sc.sim.solver.residual_threshold = 1e-9;
          });
  EXPECT_TRUE(r.survived);
  ASSERT_GE(r.swing_start, 0);
  int swing_lift_offs = 0, landings = 0, before_swing = 0;
  for (const Matched& m : r.all) {
    EXPECT_TRUE(m.matched) << "true event at tick " << m.true_tick;
    if (!m.matched) continue;
    EXPECT_LE(m.delay_ms, 5.0) << "tick " << m.true_tick;
    EXPECT_GE(m.delay_ms, -5.0) << "tick " << m.true_tick;
    if (m.true_tick < r.swing_start)
      ++before_swing;
    else
      (m.touch_down ? landings : swing_lift_offs) += 1;
  }
  EXPECT_EQ(before_swing, 2);     // the separation and the light touch-down
  EXPECT_EQ(swing_lift_offs, 1);  // the right foot leaves the ground once after the swing began
  EXPECT_EQ(landings, 1);         // and lands once
  EXPECT_LE(r.est_transitions, chatter_bound(r));
  expect_no_flag_long_in_the_air(r);
}

// The step in place with the estimator's and the controller's defaults (seed 1): the right
// foot's load fades below 1 % of W 0.06-0.4 s before the swing lifts it and it rests there with
// 0-5 N (the resting rule, on by default since 2026-12-05: the flag means "touching"); the
// swing's lift-off comes from the plan's corner rule, the landing from the impact, and the
// landed foot, touching with 2-5 N for 0.7 s before the weight comes back, keeps its flag (the
// landing rule). Every true event within 5 ms, exactly the truth's changes, no others.
TEST(ContactEvents, StepInPlaceWithTheDefaults) {
  const Result r = run("step_in_place.yaml", 8.0);
  EXPECT_TRUE(r.survived);
  ASSERT_GE(r.swing_start, 0);
  int landings = 0, lift_offs = 0;
  for (const Matched& m : r.all) {
    EXPECT_TRUE(m.matched) << "true event at tick " << m.true_tick;
    EXPECT_GE(m.true_tick, r.swing_start) << "no true change before the swing";
    if (!m.matched) continue;
    (m.touch_down ? landings : lift_offs) += 1;
    EXPECT_LE(m.delay_ms, 5.0) << "tick " << m.true_tick;
    EXPECT_GE(m.delay_ms, -5.0) << "tick " << m.true_tick;
  }
  EXPECT_EQ(lift_offs, 1);
  EXPECT_EQ(landings, 1);
  // The flag changes exactly as often as the true contact (not as the 1 % load, which crosses
  // several times while the foot rests).
  EXPECT_EQ(r.est_transitions, r.truth_raw_transitions);
  expect_no_flag_long_in_the_air(r);
}

TEST(ContactEvents, AFootRockingOnItsEdgeIsNotFlaggedInTheAir) {
  // The forward push turned forward-left at about 265 N: the right foot rolls on its outer edge
  // and taps the ground with a corner several times while its high corners come down. A rest
  // taken at such a tap (the landing rule without the stillness gate) kept the flag on for
  // 113 ms with the foot in the air; a flag on a foot in the air makes it a support.
  // Nine pushes around that one, because which corner taps when is a knife edge: the 45 deg
  // push at 265 N kept the flag 13 ms into the air with the solver's residual at 1e-7 and under
  // 10 ms at 1e-9, while its eight neighbours kept it at most 8 ms with either. The bound is
  // three times the 5 ms lift-off target: far from the 113 ms failure, and not one trajectory's
  // figure.
  int rocking = 0;
  for (double deg : {40.0, 45.0, 50.0})
    for (double force : {255.0, 265.0, 275.0}) {
      const Result r = run("forward_push_double_support.yaml", 3.0, {}, 1.0, 0, {},
                           std::numeric_limits<double>::quiet_NaN(), [&](scenario::Scenario& sc) {
                             const double a = deg * M_PI / 180.0;
                             for (sim::Push& p : sc.sim.pushes)
                               p.force_W = force * Eigen::Vector3d(std::cos(a), std::sin(a), 0.0);
                           });
      SCOPED_TRACE(std::to_string(deg) + " deg, " + std::to_string(force) + " N");
      if (r.truth_raw_transitions >= 6) ++rocking;
      EXPECT_LE(r.est_transitions, chatter_bound(r));
      EXPECT_LE(r.longest_flag_in_air_ms, 15.0);
    }
  EXPECT_GE(rocking, 5) << "the feet must rock for this check to mean anything";
}

TEST(ContactEvents, NoChatterWhileTheFeetSlide) {
  // Issue #20 measured 38 flag changes against 30 true ones with the load-threshold detector on
  // the paper's forward push at 250 N (the feet slid and tipped). Today's controller keeps both
  // feet flat and still at 250 N and falls from 262 N (no contact changes before the fall), so
  // the feet are made to slide: the forward push at 200 N on a ground of friction 0.15 (the
  // controller plans with its own mu). Both feet slide and stay loaded; no flag may change.
  const Result r = run("forward_push_double_support.yaml", 3.0, {}, 200.0 / 120.0, 0, {}, 0.15);
  EXPECT_GT(r.foot_slip_max_m, 0.005) << "the feet must slide for this check to mean anything";
  EXPECT_LE(r.est_transitions, chatter_bound(r));
  expect_no_flag_long_in_the_air(r);
  expect_delays_within(r, 5.0, 5.0);
}

}  // namespace
}  // namespace poise::inprocess
namespace poise::inprocess {
namespace {
// Measurements, not checks (ctest does not run them):
// build/tests/poise_estimator_contact_events_test
// --gtest_also_run_disabled_tests --gtest_filter='*DISABLED*' prints every event's delay for
// sensor-noise seeds 1-8 (POISE_CONTACT_EVENTS_SEED=N: one of them; POISE_CONTACT_EVENTS_STEP=
// FILE another step scenario of deploy/scenarios) and for lateral pushes of 140-200 N;
// POISE_CONTACT_EVENTS_CSV=DIR writes the ticks; POISE_CONTACT_EVENTS_FT_NOISE=0 turns the
// light-touch rule off.
TEST(ContactEvents, DISABLED_Seeds) {
  const char* only = std::getenv("POISE_CONTACT_EVENTS_SEED");
  for (std::uint64_t seed = 1; seed <= 8; ++seed) {
    if (only && std::atoi(only) != static_cast<int>(seed)) continue;
    std::printf("=== step seed %d\n", static_cast<int>(seed));
    const char* step = std::getenv("POISE_CONTACT_EVENTS_STEP");  // another scenario file
    run(step ? step : "step_in_place.yaml", 8.0, {}, 1.0, seed);
    std::printf("=== lateral seed %d\n", static_cast<int>(seed));
    run("lateral_push_unloads_foot.yaml", 3.0, {}, 1.0, seed);
  }
}
TEST(ContactEvents, DISABLED_Scan) {
  for (double f : {140.0, 150.0, 160.0, 170.0, 180.0, 190.0, 200.0}) {
    std::printf("=== lateral %.0f N\n", f);
    run("lateral_push_unloads_foot.yaml", 3.0, {}, f / 175.0);
  }
}
}  // namespace
}  // namespace poise::inprocess
