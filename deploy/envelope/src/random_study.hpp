#pragma once
// `poise envelope random` and `poise envelope merge`: the balance envelope drawn at random
// (deploy/envelope/README.md "The random study"). Every run's push (support, direction, height,
// start, duration, impulse) and model draw come from the study seed and the run's index alone,
// so a study split into shards (--shard I/N, on any number of machines) and merged is the same
// study, run for run.
#include <cmath>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace poise::envelope {

/// What is drawn, per run.
struct SamplingOptions {
  double single_fraction = 0.5;            ///< share of runs in single support
  double impulse_double[2] = {10.0, 45.0};  ///< N s, uniform
  double impulse_single[2] = {4.0, 24.0};   ///< N s, uniform
  double duration[2] = {0.05, 0.2};         ///< s, uniform
  double height[2] = {-0.05, 0.15};         ///< m, added to the base push point's z (link frame)
  double start_spread = 0.5;                ///< s, start = base start + uniform [0, spread]
};

struct Sample {
  int index = 0;
  std::string support;  ///< double | single
  double direction_deg = 0.0, height_m = 0.0, start_s = 0.0, duration_s = 0.0;
  double impulse_ns = 0.0, force_n = 0.0;
  std::uint64_t model_seed = 0;  ///< the run's reality seed (used with a reality profile)
};

/// The push of run `index` of the study `seed` (base_start: the base scenario's push start).
Sample draw_sample(std::uint64_t seed, int index, const SamplingOptions& o, double base_start);

/// One finished run.
struct RunRecord {
  Sample s;
  bool survived = false;
  std::string kind;    ///< "" survived, else fall | slip | tilt | slow recovery | error | other
  std::string failed;  ///< the failed criteria, readable
  double com_error_max_m = 0.0, foot_slip_max_m = 0.0;
};

/// What kind of failure a run's failed criteria describe, the most severe that applies:
/// "error", "fall", "slip", "tilt", "slow recovery" or "other" (deploy/envelope/README.md).
std::string failure_kind(const std::string& failed);

/// Wilson score interval of k successes in n trials at z (1.96: 95 %).
std::pair<double, double> wilson_interval(int k, int n, double z = 1.96);

/// Logistic survival model P(J) = 1 / (1 + exp((J - j50) / scale)), fitted by maximum
/// likelihood (Newton's method). nullopt when the data cannot fix it (all survived, all failed,
/// or fully separated: then the boundary lies between the largest survival and the smallest
/// failure).
struct LogisticFit {
  double j50 = 0.0, scale = 1.0;
  double at(double p) const;  ///< the impulse at survival probability p
};
std::optional<LogisticFit> fit_logistic(const std::vector<double>& impulse,
                                        const std::vector<bool>& survived);

/// The study's figures for one support (RandomReport::supports).
struct SupportReport {
  std::string support;
  int runs = 0, survived = 0;
  struct Bin {
    double lo = 0.0, hi = 0.0;
    int runs = 0, survived = 0;
    double ci_lo = 0.0, ci_hi = 0.0;
  };
  std::vector<Bin> bins;
  std::optional<LogisticFit> fit;
  double j95 = std::nan(""), j95_lo = std::nan(""), j95_hi = std::nan("");  ///< bootstrap 95 %
  double smallest_failure = std::nan(""), largest_survival = std::nan("");
  struct Sector {
    double from_deg = 0.0, to_deg = 0.0;
    int runs = 0, survived = 0;
    double smallest_failure = std::nan("");
  };
  std::vector<Sector> worst;  ///< the sectors whose smallest failed impulse is lowest
  int non_monotone = 0;       ///< survivals above a smaller failure of the same direction band
};

struct ReportOptions {
  double bin_ns = 2.5;      ///< impulse bin width of the table
  double band_deg = 10.0;   ///< direction band of the non-monotone count
  double sector_deg = 22.5; ///< direction sector of the worst-directions list
  int worst = 3;
  int bootstrap = 200;
};

std::vector<SupportReport> analyse(const std::vector<RunRecord>& runs, const ReportOptions& o,
                                   std::uint64_t seed);

int random_main(int argc, char** argv);  ///< poise envelope random
int merge_main(int argc, char** argv);   ///< poise envelope merge

}  // namespace poise::envelope
