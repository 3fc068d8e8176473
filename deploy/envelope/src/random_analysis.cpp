// The random study's sampling and statistics (random_study.hpp): what each run draws, Wilson
// intervals, the logistic survival fit and its bootstrap, worst directions, non-monotone bands.
#include <algorithm>
#include <cmath>
#include <limits>
#include <tuple>

#include "random_study.hpp"

namespace poise::envelope {
namespace {

/// SplitMix64: a well-mixed 64-bit hash; the study's per-run streams come from it (the same
/// numbers on every platform, unlike std's distributions).
std::uint64_t splitmix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Uniform numbers in [0, 1) from one stream.
class Stream {
 public:
  explicit Stream(std::uint64_t seed) : state_(seed) {}
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double in(const double (&range)[2]) { return range[0] + (range[1] - range[0]) * uniform(); }
  std::uint64_t next() { return state_ = splitmix(state_); }

 private:
  std::uint64_t state_;
};

double sigmoid(double x) { return 1.0 / (1.0 + std::exp(-x)); }

}  // namespace

/// What kind of failure a run's failed criteria describe, the most severe that applies:
/// "error" (the run did not run to its end), "fall" (CoM error over its maximum, the base too
/// low, a non-foot contact), "slip" (a foot's sole centre), "tilt", "slow recovery" (the CoM not
/// back within com_error_final in time).
std::string failure_kind(const std::string& failed) {
  const auto has = [&](const char* s) { return failed.find(s) != std::string::npos; };
  if (has("error:") || has("aborted")) return "error";
  if (has("com_error_max") || has("min_base_height") || has("non_foot_contacts")) return "fall";
  if (has("foot_slip_max")) return "slip";
  if (has("foot_tilt_max")) return "tilt";
  if (has("com_error_final") || has("recovery_time")) return "slow recovery";
  return "other";
}

Sample draw_sample(std::uint64_t seed, int index, const SamplingOptions& o, double base_start) {
  Stream z(splitmix(seed) ^ splitmix(0x5a5a0000ULL + static_cast<std::uint64_t>(index)));
  Sample s;
  s.index = index;
  s.support = z.uniform() < o.single_fraction ? "single" : "double";
  s.direction_deg = 360.0 * z.uniform();
  s.height_m = z.in(o.height);
  s.start_s = base_start + o.start_spread * z.uniform();
  s.duration_s = z.in(o.duration);
  s.impulse_ns = z.in(s.support == "single" ? o.impulse_single : o.impulse_double);
  s.force_n = s.impulse_ns / s.duration_s;
  s.model_seed = z.next() >> 11;  // within 2^53: a scenario's seed
  return s;
}

std::pair<double, double> wilson_interval(int k, int n, double z) {
  if (n <= 0) return {0.0, 1.0};
  const double p = static_cast<double>(k) / n, z2 = z * z, nn = n;
  const double centre = (p + z2 / (2 * nn)) / (1 + z2 / nn);
  const double half = z / (1 + z2 / nn) * std::sqrt(p * (1 - p) / nn + z2 / (4 * nn * nn));
  return {std::max(0.0, centre - half), std::min(1.0, centre + half)};
}

double LogisticFit::at(double p) const { return j50 + scale * std::log(1.0 / p - 1.0); }

std::optional<LogisticFit> fit_logistic(const std::vector<double>& impulse,
                                        const std::vector<bool>& survived) {
  const std::size_t n = impulse.size();
  if (n < 2) return std::nullopt;
  double max_ok = -std::numeric_limits<double>::infinity();
  double min_fail = std::numeric_limits<double>::infinity();
  double mean = 0.0;
  int k = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mean += impulse[i] / static_cast<double>(n);
    if (survived[i]) {
      ++k;
      max_ok = std::max(max_ok, impulse[i]);
    } else {
      min_fail = std::min(min_fail, impulse[i]);
    }
  }
  if (k == 0 || k == static_cast<int>(n) || max_ok < min_fail) return std::nullopt;
  // logit P = b0 + b1 (J - mean), Newton's method on the log-likelihood (concave).
  double b0 = std::log(static_cast<double>(k) / (static_cast<double>(n) - k)), b1 = 0.0;
  for (int it = 0; it < 100; ++it) {
    double g0 = 0, g1 = 0, h00 = 0, h01 = 0, h11 = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const double x = impulse[i] - mean;
      const double p = sigmoid(b0 + b1 * x), w = p * (1 - p);
      const double y = survived[i] ? 1.0 : 0.0;
      g0 += y - p;
      g1 += (y - p) * x;
      h00 += w;
      h01 += w * x;
      h11 += w * x * x;
    }
    const double det = h00 * h11 - h01 * h01;
    if (!(det > 0.0)) return std::nullopt;
    const double d0 = (h11 * g0 - h01 * g1) / det, d1 = (h00 * g1 - h01 * g0) / det;
    b0 += d0;
    b1 += d1;
    if (std::abs(d0) < 1e-10 && std::abs(d1) < 1e-12) break;
    if (it == 99) return std::nullopt;
  }
  if (!(b1 < 0.0) || !std::isfinite(b0)) return std::nullopt;  // survival must fall with impulse
  LogisticFit f;
  f.scale = -1.0 / b1;
  f.j50 = mean - b0 / b1;
  return f;
}

namespace {

SupportReport::Bin bin_of(const std::vector<const RunRecord*>& runs, double lo, double hi) {
  SupportReport::Bin b{lo, hi, 0, 0, 0.0, 1.0};
  for (const RunRecord* r : runs)
    if (r->s.impulse_ns >= lo && r->s.impulse_ns < hi) {
      ++b.runs;
      b.survived += r->survived ? 1 : 0;
    }
  std::tie(b.ci_lo, b.ci_hi) = wilson_interval(b.survived, b.runs);
  return b;
}

/// The 2.5 and 97.5 percentiles of the 95 %-survival impulse over bootstrap resamples.
std::pair<double, double> bootstrap_j95(const std::vector<const RunRecord*>& runs, int resamples,
                                        std::uint64_t seed) {
  const double nan = std::nan("");
  Stream z(splitmix(seed ^ 0xb007ULL));
  std::vector<double> j95;
  std::vector<double> imp(runs.size());
  std::vector<bool> ok(runs.size());
  for (int b = 0; b < resamples; ++b) {
    for (std::size_t i = 0; i < runs.size(); ++i) {
      const RunRecord* r = runs[static_cast<std::size_t>(z.uniform() * static_cast<double>(runs.size()))];
      imp[i] = r->s.impulse_ns;
      ok[i] = r->survived;
    }
    if (const auto f = fit_logistic(imp, ok)) j95.push_back(f->at(0.95));
  }
  if (2 * j95.size() < static_cast<std::size_t>(resamples)) return {nan, nan};
  std::sort(j95.begin(), j95.end());
  const auto pct = [&](double p) {
    return j95[std::min(j95.size() - 1, static_cast<std::size_t>(p * static_cast<double>(j95.size())))];
  };
  return {pct(0.025), pct(0.975)};
}

int count_non_monotone(const std::vector<const RunRecord*>& runs, double band_deg) {
  int count = 0;
  for (const RunRecord* r : runs) {
    if (!r->survived) continue;
    const int band = static_cast<int>(r->s.direction_deg / band_deg);
    for (const RunRecord* f : runs)
      if (!f->survived && static_cast<int>(f->s.direction_deg / band_deg) == band &&
          f->s.impulse_ns < r->s.impulse_ns) {
        ++count;
        break;
      }
  }
  return count;
}

std::vector<SupportReport::Sector> worst_sectors(const std::vector<const RunRecord*>& runs,
                                                 double sector_deg, int worst) {
  std::vector<SupportReport::Sector> sectors;
  for (double from = 0.0; from < 360.0 - 1e-9; from += sector_deg) {
    SupportReport::Sector s;
    s.from_deg = from;
    s.to_deg = std::min(360.0, from + sector_deg);
    for (const RunRecord* r : runs)
      if (r->s.direction_deg >= s.from_deg && r->s.direction_deg < s.to_deg) {
        ++s.runs;
        s.survived += r->survived ? 1 : 0;
        if (!r->survived && !(r->s.impulse_ns >= s.smallest_failure))
          s.smallest_failure = r->s.impulse_ns;
      }
    if (std::isfinite(s.smallest_failure)) sectors.push_back(s);
  }
  std::sort(sectors.begin(), sectors.end(), [](const auto& a, const auto& b) {
    return a.smallest_failure < b.smallest_failure;
  });
  if (sectors.size() > static_cast<std::size_t>(worst)) sectors.resize(static_cast<std::size_t>(worst));
  return sectors;
}

SupportReport analyse_support(const std::string& support, const std::vector<RunRecord>& all,
                              const ReportOptions& o, std::uint64_t seed) {
  SupportReport rep;
  rep.support = support;
  std::vector<const RunRecord*> runs;
  for (const RunRecord& r : all)
    if (r.s.support == support) runs.push_back(&r);
  rep.runs = static_cast<int>(runs.size());
  if (runs.empty()) return rep;
  double lo = std::numeric_limits<double>::infinity(), hi = -lo;
  std::vector<double> imp;
  std::vector<bool> ok;
  for (const RunRecord* r : runs) {
    rep.survived += r->survived ? 1 : 0;
    lo = std::min(lo, r->s.impulse_ns);
    hi = std::max(hi, r->s.impulse_ns);
    imp.push_back(r->s.impulse_ns);
    ok.push_back(r->survived);
    if (r->survived && !(r->s.impulse_ns <= rep.largest_survival))
      rep.largest_survival = r->s.impulse_ns;
    if (!r->survived && !(r->s.impulse_ns >= rep.smallest_failure))
      rep.smallest_failure = r->s.impulse_ns;
  }
  for (double b = std::floor(lo / o.bin_ns) * o.bin_ns; b <= hi; b += o.bin_ns)
    rep.bins.push_back(bin_of(runs, b, b + o.bin_ns));
  rep.fit = fit_logistic(imp, ok);
  if (rep.fit) {
    rep.j95 = rep.fit->at(0.95);
    std::tie(rep.j95_lo, rep.j95_hi) =
        bootstrap_j95(runs, o.bootstrap, seed ^ (support == "single" ? 1ULL : 2ULL));
  }
  rep.worst = worst_sectors(runs, o.sector_deg, o.worst);
  rep.non_monotone = count_non_monotone(runs, o.band_deg);
  return rep;
}

}  // namespace

std::vector<SupportReport> analyse(const std::vector<RunRecord>& runs, const ReportOptions& o,
                                   std::uint64_t seed) {
  std::vector<SupportReport> out;
  for (const char* support : {"double", "single"}) {
    SupportReport r = analyse_support(support, runs, o, seed);
    if (r.runs > 0) out.push_back(std::move(r));
  }
  return out;
}

}  // namespace poise::envelope
