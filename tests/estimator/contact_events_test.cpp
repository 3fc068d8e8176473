// Contact detection delays against the simulator's truth (#20 item 3), closed loop in process
// with the industrial sensor defaults (simulator/sim/SENSORS.md): the estimator's contact flags
// drive the controller. Scenarios in which contacts change: a drop onto the feet, a lateral
// push that lifts a foot, a step in place (deploy/scenarios/step_in_place.yaml: its balance
// reference swings the right foot 3 cm up and down, played by the in-process loop).
//
// Truth events: transitions of GroundTruth in_contact that then hold for 10 ticks (contact
// bounces at an impact are one event). Each is matched with the estimate's nearest transition
// of the same kind within 100 ms; delay = estimated tick - the tick of the true change of that
// kind nearest to it among the event and the bounces of the 20 ticks before it (a foot that taps
// the ground before it settles touches down several times; negative: early).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <cstdio>
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
/// height, planned foot mode), to look at what the flags follow.
std::FILE* open_csv(const std::string& file) {
  const char* dir = std::getenv("POISE_CONTACT_EVENTS_CSV");
  if (dir == nullptr || *dir == 0) return nullptr;
  std::FILE* out = std::fopen((std::string(dir) + "/" + file + ".csv").c_str(), "w");
  if (out) std::fprintf(out, "tick,side,truth,est,fn_meas,fn_true,foot_z_true,mode,foot_z_est\n");
  return out;
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
  int truth_transitions = 0;      ///< debounced (events)
  int truth_raw_transitions = 0;  ///< every change of the true flag (bounces included)
  int truth_loaded_transitions = 0;  ///< every change of FootLog::truth_loaded
  int est_transitions = 0;
  bool survived = false;
  std::vector<Matched> all;  ///< every true event of both feet
  long swing_start = -1;     ///< first tick at which the reference planned a swing (-1: never)
};

using Reference = std::function<void(InProcessLoop&, double)>;

Result run(const std::string& file, double duration, const Reference& reference = {},
           double push_scale = 1.0) {
  scenario::Scenario sc =
      scenario::load_scenario(std::string(POISE_SOURCE_DIR) + "/deploy/scenarios/" + file);
  for (sim::Push& p : sc.sim.pushes)
    p.force_W *= push_scale;
  LoopOptions opt;
  opt.duration = duration;
  InProcessLoop loop(sc, opt);
  const double weight = loop.controller().model().total_mass * loop.controller().model().gravity.norm();
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
    std::array<double, 2> fn_true{}, z_true{};
    for (int side = 0; side < 2; ++side) {
      const auto& tf = loop.truth().feet[static_cast<std::size_t>(sim_foot[side])];
      truth[side] = tf.in_contact;
      fn_true[side] = (tf.X_WF.linear().transpose() * tf.force_W).z();
      z_true[side] = tf.X_WF.translation().z();
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
        std::fprintf(csv, "%d,%d,%d,%d,%.3f,%.3f,%.5f,%d,%.5f\n", k, side, truth[side],
                     loop.state().feet[side].in_contact ? 1 : 0,
                     loop.state().feet[side].normal_force, fn_true[side], z_true[side],
                     static_cast<int>(loop.reference().feet[side].mode),
                     loop.state().feet[side].X_WF.p.z());
    }
  }
  if (csv) std::fclose(csv);
  Result r;
  r.swing_start = swing_start;
  const RunResult lr = loop.result();
  r.survived = lr.survived;
  std::printf("  verdict: CoM error max %.3f m, foot slip max %.3f m, non-foot contact ticks %d, "
              "base height min %.3f m\n",
              lr.com_error_max_m, lr.foot_slip_max_m, lr.non_foot_contacts, lr.min_base_height_m);
  const double ms = loop.simulator().dt() * 1e3;
  for (int side = 0; side < 2; ++side) {
    const auto te = events(log[side].truth, 10);
    const auto ee = events(log[side].est, 1);
    r.truth_transitions += static_cast<int>(te.size());
    r.est_transitions += transitions(log[side].est);
    r.truth_raw_transitions += transitions(log[side].truth);
    r.truth_loaded_transitions += transitions(log[side].truth_loaded);
    if (std::getenv("POISE_CONTACT_EVENTS_TRACE"))
      for (std::size_t k = 1; k < log[side].est.size(); ++k)
        if (log[side].est[k] != log[side].est[k - 1] || log[side].truth[k] != log[side].truth[k - 1])
          std::printf("  foot %d tick %zu truth %d estimate %d\n", side, k, log[side].truth[k],
                      log[side].est[k]);
    // Every raw change of the truth (bounces included): a foot that taps the ground before it
    // settles makes several true touch-downs, and the estimate may follow each of them.
    const auto raw = events(log[side].truth, 1);
    for (const Event& t : te) {
      long best = 1000000;
      for (const Event& e : ee)
        if (e.touch_down == t.touch_down && std::abs(e.tick - t.tick) < std::abs(best))
          best = e.tick - t.tick;
      if (std::abs(best) > 100) {
        ++r.unmatched;
        r.all.push_back(Matched{t.tick, t.touch_down, false, 0.0});
        std::printf("  unmatched true %s of foot %d at tick %ld\n",
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
      (t.touch_down ? r.touch_down_ms : r.lift_off_ms).push_back(static_cast<double>(delay) * ms);
      r.all.push_back(Matched{t.tick, t.touch_down, true, static_cast<double>(delay) * ms});
    }
  }
  std::printf(
      "%-32s survived %d | truth events %d (raw changes %d, loaded > 1 %% W changes %d), "
      "estimate changes %d, unmatched %d\n",
      file.c_str(), r.survived, r.truth_transitions, r.truth_raw_transitions,
      r.truth_loaded_transitions, r.est_transitions, r.unmatched);
  for (double d : r.touch_down_ms)
    std::printf("  touch-down delay %+.0f ms\n", d);
  for (double d : r.lift_off_ms)
    std::printf("  lift-off delay   %+.0f ms\n", d);
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

TEST(ContactEvents, DropOntoTheFeet) {
  const Result r = run("drop_onto_feet.yaml", 1.5);
  EXPECT_TRUE(r.survived);
  EXPECT_EQ(r.touch_down_ms.size(), 2u);  // each foot lands once (bounces are one event)
  expect_delays_within(r, 5.0, 5.0);
  // No chatter: the flags change no more often than the truth, whose impact bounces (a few ms
  // off the ground) they follow.
  EXPECT_LE(r.est_transitions, chatter_bound(r));
}

TEST(ContactEvents, LateralPushLiftsAFoot) {
  const Result r = run("lateral_push_unloads_foot.yaml", 3.0);
  EXPECT_TRUE(r.survived);
  EXPECT_GE(r.lift_off_ms.size(), 1u);  // the push lifts a foot
  EXPECT_GE(r.touch_down_ms.size(), 1u);
  expect_delays_within(r, 5.0, 5.0);
  EXPECT_LE(r.est_transitions, chatter_bound(r));
}

TEST(ContactEvents, StepInPlace) {
  // The weight goes over the left foot, then the reference swings the right foot (FOOT_SWING,
  // the contact detector's prior: contact_detector.hpp) and sets it down. The swing's lift-off
  // and the landing are checked against the 5 ms target. Before the swing the right foot rests
  // with 0-3 N: the flag drops when the load falls below 1 % of the weight (with the resting
  // rule off it means "loaded"), and the simulator's contact there came and went
  // with no load (< 1 N) and no motion: those true changes are printed, and must all come
  // before the swing. Measured (seed 1, 2026-12-02, before a01ba9d): swing lift-off 4 ms early (7 ms early
  // without the plan), landing at the tick of the truth; before the swing the flag is off from
  // 0.11 s before a 20 ms true separation until 0.19 s after it (2 true changes unmatched).
  // The detector's resting rule (EstimatorConfig::contact_rest_time, off by default) keeps that
  // flag on (2 flag changes against 2 true ones, every event within 5 ms, in process), but in
  // real time it delayed the swing's lift-off past 5 ms (idl/README.md "Contact flags").
  const Result r = run("step_in_place.yaml", 8.0);
  EXPECT_TRUE(r.survived);
  ASSERT_GE(r.swing_start, 0);
  int swing_lift_offs = 0, landings = 0;
  for (const Matched& m : r.all) {
    if (m.true_tick < r.swing_start) continue;  // printed by run()
    EXPECT_TRUE(m.matched) << "true event at tick " << m.true_tick << " after the swing began";
    if (!m.matched) continue;
    (m.touch_down ? landings : swing_lift_offs) += 1;
    EXPECT_LE(m.delay_ms, 5.0) << "tick " << m.true_tick;
    EXPECT_GE(m.delay_ms, -5.0) << "tick " << m.true_tick;
  }
  EXPECT_EQ(swing_lift_offs, 1);  // the right foot leaves the ground once after the swing began
  EXPECT_EQ(landings, 1);         // and lands once
  EXPECT_LE(r.est_transitions, chatter_bound(r) + 2);
}

TEST(ContactEvents, NoChatterWhenAStrongPushSlidesTheFeet) {
  // The paper's forward push at 250 N (x 0.1 s): the feet slide and tip (issue #20 measured 38
  // flag changes against 30 true ones with the load-threshold detector).
  const Result r = run("forward_push_double_support.yaml", 3.0, {}, 250.0 / 120.0);
  EXPECT_LE(r.est_transitions, chatter_bound(r));
  expect_delays_within(r, 5.0, 5.0);
}

}  // namespace
}  // namespace poise::inprocess
