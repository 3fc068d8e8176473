// The random study's statistics (deploy/envelope/src/random_study.hpp) against independent
// values: Wilson intervals from the closed form's published figures, the logistic fit recovering
// the parameters of seeded synthetic survival data, the draws' ranges and uniformity, and the
// non-monotone count and worst sectors on hand-made runs.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include "random_study.hpp"

namespace poise::envelope {
namespace {

// Wilson score intervals at 95 % (z = 1.96), as tabulated by Newcombe (1998), Table I, method 3:
// 81/263 -> 0.2553-0.3662; 15/148 -> 0.0624-0.1605; 0/20 -> 0-0.1611; 1/29 -> 0.0061-0.1718.
TEST(RandomStats, WilsonIntervalMatchesNewcombesTable) {
  const struct {
    int k, n;
    double lo, hi;
  } cases[] = {{81, 263, 0.2553, 0.3662}, {15, 148, 0.0624, 0.1605}, {0, 20, 0.0, 0.1611},
               {1, 29, 0.0061, 0.1718}};
  for (const auto& c : cases) {
    const auto [lo, hi] = wilson_interval(c.k, c.n);
    EXPECT_NEAR(lo, c.lo, 1e-4) << c.k << "/" << c.n;
    EXPECT_NEAR(hi, c.hi, 1e-4) << c.k << "/" << c.n;
  }
  const auto [lo, hi] = wilson_interval(0, 0);
  EXPECT_EQ(lo, 0.0);
  EXPECT_EQ(hi, 1.0);
}

// Survival drawn from a known logistic law, P(J) = 1 / (1 + exp((J - 25) / 2)): the maximum
// likelihood fit finds j50 and the scale within a few standard errors, and the 95 % impulse is
// j50 - scale ln 19.
TEST(RandomStats, LogisticFitRecoversAKnownLaw) {
  std::mt19937_64 rng(20261207);
  std::uniform_real_distribution<double> J(10.0, 40.0), u(0.0, 1.0);
  for (const double scale : {1.0, 2.0, 4.0}) {
    std::vector<double> imp;
    std::vector<bool> ok;
    for (int i = 0; i < 6000; ++i) {
      imp.push_back(J(rng));
      ok.push_back(u(rng) < 1.0 / (1.0 + std::exp((imp.back() - 25.0) / scale)));
    }
    const auto fit = fit_logistic(imp, ok);
    ASSERT_TRUE(fit.has_value()) << scale;
    EXPECT_NEAR(fit->j50, 25.0, 0.1 + 0.1 * scale) << scale;
    EXPECT_NEAR(fit->scale, scale, 0.1 * scale) << scale;
    EXPECT_NEAR(fit->at(0.95), fit->j50 - fit->scale * std::log(19.0), 1e-12);
    EXPECT_NEAR(fit->at(0.5), fit->j50, 1e-12);
  }
  // No law to fit: all survived, all failed, or a clean separation.
  EXPECT_FALSE(fit_logistic({1, 2, 3}, {true, true, true}));
  EXPECT_FALSE(fit_logistic({1, 2, 3}, {false, false, false}));
  EXPECT_FALSE(fit_logistic({1, 2, 3, 4}, {true, true, false, false}));
  // Survival that grows with impulse is not a balance envelope.
  EXPECT_FALSE(fit_logistic({1, 2, 3, 4, 5, 6}, {false, false, true, false, true, true}));
}

TEST(RandomStats, DrawsAreSeededInRangeAndUniform) {
  SamplingOptions o;
  const Sample a = draw_sample(42, 17, o, 1.0), b = draw_sample(42, 17, o, 1.0);
  EXPECT_EQ(a.direction_deg, b.direction_deg);
  EXPECT_EQ(a.model_seed, b.model_seed);
  EXPECT_NE(draw_sample(43, 17, o, 1.0).direction_deg, a.direction_deg);
  EXPECT_NE(draw_sample(42, 18, o, 1.0).direction_deg, a.direction_deg);
  int single = 0, quadrant[4] = {0, 0, 0, 0};
  const int n = 8000;
  for (int i = 0; i < n; ++i) {
    const Sample s = draw_sample(7, i, o, 1.0);
    ASSERT_GE(s.direction_deg, 0.0);
    ASSERT_LT(s.direction_deg, 360.0);
    ASSERT_GE(s.duration_s, o.duration[0]);
    ASSERT_LE(s.duration_s, o.duration[1]);
    ASSERT_GE(s.height_m, o.height[0]);
    ASSERT_LE(s.height_m, o.height[1]);
    ASSERT_GE(s.start_s, 1.0);
    ASSERT_LE(s.start_s, 1.0 + o.start_spread);
    const double* range = s.support == "single" ? o.impulse_single : o.impulse_double;
    ASSERT_GE(s.impulse_ns, range[0]);
    ASSERT_LE(s.impulse_ns, range[1]);
    ASSERT_NEAR(s.force_n * s.duration_s, s.impulse_ns, 1e-9);
    ASSERT_LT(s.model_seed, 1ULL << 53);
    single += s.support == "single" ? 1 : 0;
    ++quadrant[static_cast<int>(s.direction_deg / 90.0)];
  }
  // Binomial standard deviations: sqrt(n p (1 - p)) = 45 (half) and 39 (a quarter); 4 sigma.
  EXPECT_NEAR(single, n / 2, 4 * 45);
  for (int q : quadrant) EXPECT_NEAR(q, n / 4, 4 * 39);
  SamplingOptions doubles = o;
  doubles.single_fraction = 0.0;
  for (int i = 0; i < 100; ++i) EXPECT_EQ(draw_sample(1, i, doubles, 1.0).support, "double");
}

RunRecord record(int index, double dir, double impulse, bool ok) {
  RunRecord r;
  r.s.index = index;
  r.s.support = "double";
  r.s.direction_deg = dir;
  r.s.impulse_ns = impulse;
  r.survived = ok;
  r.kind = ok ? "" : "fall";
  return r;
}

// Non-monotone: a survival above a smaller failure of the same 10 deg band counts once; other
// bands do not mix. Worst sectors: the lowest smallest failure first.
TEST(RandomStats, NonMonotoneRunsAndWorstDirections) {
  const std::vector<RunRecord> runs = {
      record(0, 5.0, 20.0, false),   // band 0: fails at 20
      record(1, 7.0, 25.0, true),    //   survives above it: non-monotone
      record(2, 8.0, 30.0, true),    //   and again
      record(3, 3.0, 15.0, true),    //   below it: fine
      record(4, 15.0, 10.0, false),  // band 1: fails at 10
      record(5, 45.0, 30.0, true),   // band 4: nothing failed
      record(6, 95.0, 12.0, false),  // sector 4 (90-112.5): fails at 12
      record(7, 100.0, 11.0, true),
  };
  ReportOptions o;
  const auto reps = analyse(runs, o, 1);
  ASSERT_EQ(reps.size(), 1u);
  EXPECT_EQ(reps[0].runs, 8);
  EXPECT_EQ(reps[0].survived, 5);
  EXPECT_EQ(reps[0].non_monotone, 2);
  EXPECT_EQ(reps[0].smallest_failure, 10.0);
  EXPECT_EQ(reps[0].largest_survival, 30.0);
  ASSERT_EQ(reps[0].worst.size(), 2u);  // two sectors have failures
  EXPECT_EQ(reps[0].worst[0].from_deg, 0.0);
  EXPECT_EQ(reps[0].worst[0].smallest_failure, 10.0);
  EXPECT_EQ(reps[0].worst[1].from_deg, 90.0);
  EXPECT_EQ(reps[0].worst[1].smallest_failure, 12.0);
  // The bins hold every run once.
  int in_bins = 0;
  for (const auto& b : reps[0].bins) in_bins += b.runs;
  EXPECT_EQ(in_bins, 8);
}

}  // namespace
}  // namespace poise::envelope
