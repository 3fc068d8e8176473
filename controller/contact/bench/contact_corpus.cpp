#include "contact_corpus.hpp"

#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <stdexcept>

#include <Eigen/Geometry>

namespace poise::contact::bench {

namespace {

constexpr const char* kHeader = "# poise contact corpus v1";

double uni(std::mt19937& rng, double lo, double hi) {
  return std::uniform_real_distribution<double>(lo, hi)(rng);
}

ContactProblem geometry(std::mt19937& rng, bool right, bool left) {
  const double tilt = 10.0 * M_PI / 180.0;
  ContactProblem p;
  p.mass = uni(rng, 30.0, 80.0);
  p.com = Eigen::Vector3d(uni(rng, -0.05, 0.05), uni(rng, -0.05, 0.05), uni(rng, 0.6, 0.9));
  for (int i = 0; i < kMaxFeet; ++i) {
    FootContact& f = p.feet[i];
    f.in_contact = i == 0 ? right : left;
    f.R_WF = (Eigen::AngleAxisd(uni(rng, -0.3, 0.3), Eigen::Vector3d::UnitZ()) *
              Eigen::AngleAxisd(uni(rng, -tilt, tilt), Eigen::Vector3d::UnitY()) *
              Eigen::AngleAxisd(uni(rng, -tilt, tilt), Eigen::Vector3d::UnitX()))
                 .toRotationMatrix();
    f.p_WF = Eigen::Vector3d(uni(rng, -0.1, 0.1), (i == 0 ? -1.0 : 1.0) * uni(rng, 0.08, 0.15),
                             uni(rng, 0.05, 0.12));
    f.sole = {uni(rng, -0.1, -0.05), uni(rng, 0.1, 0.15), uni(rng, -0.06, -0.04),
              uni(rng, 0.04, 0.06)};
    f.safety_margin = uni(rng, 0.0, 0.01);
    f.ankle_height = uni(rng, 0.04, 0.1);
    f.mu = uni(rng, 0.3, 1.0);
    f.mu_torsion = uni(rng, 0.005, 0.05);
  }
  return p;
}

void make_feasible(std::mt19937& rng, ContactProblem& p) {
  const int n = (p.feet[0].in_contact ? 1 : 0) + (p.feet[1].in_contact ? 1 : 0);
  p.l_dot_desired = p.mass * p.gravity;
  p.k_dot_desired.setZero();
  for (int i = 0; i < kMaxFeet; ++i) {
    const FootContact& foot = p.feet[i];
    if (!foot.in_contact) continue;
    const double f_n = uni(rng, 0.2, 1.8) * p.mass * 9.81 / n;
    const double a = uni(rng, -1.0, 1.0);
    const double budget = uni(rng, 0.0, 0.95) * foot.mu * f_n;
    const Eigen::Vector3d f_F(a * budget,
                              (1.0 - std::abs(a)) * budget * (uni(rng, 0, 1) < 0.5 ? -1 : 1), f_n);
    const Eigen::Vector4d r = safe_region(foot);
    const FootWrench w =
        make_foot_wrench(foot, foot.R_WF * f_F, uni(rng, r[0], r[1]), uni(rng, r[2], r[3]),
                         uni(rng, -1.0, 1.0) * foot.mu_torsion * f_n);
    p.l_dot_desired += w.force_W;
    p.k_dot_desired += (foot.p_WF - p.com).cross(w.force_W) + w.torque_ankle_W;
  }
}

void make_arbitrary(std::mt19937& rng, ContactProblem& p) {
  const double mg = p.mass * 9.81;
  std::normal_distribution<double> nd(0.0, 1.0);
  for (int k = 0; k < 3; ++k) {
    p.l_dot_desired[k] = 0.5 * mg * nd(rng);
    p.k_dot_desired[k] = 0.3 * mg * nd(rng);
  }
}

}  // namespace

const char* to_string(Kind k) {
  switch (k) {
    case Kind::kFeasibleDouble:
      return "feasible_double";
    case Kind::kFeasibleSingle:
      return "feasible_single";
    case Kind::kArbitraryDouble:
      return "arbitrary_double";
    case Kind::kArbitrarySingle:
      return "arbitrary_single";
    case Kind::kRecordedDouble:
      return "recorded_double";
    case Kind::kRecordedSingle:
      return "recorded_single";
  }
  return "unknown";
}

std::vector<CorpusEntry> generate_corpus(int count, std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::vector<CorpusEntry> corpus;
  corpus.reserve(count);
  for (int i = 0; i < count; ++i) {
    const double u = uni(rng, 0.0, 1.0);
    const Kind kind = u < 0.40   ? Kind::kFeasibleDouble
                      : u < 0.60 ? Kind::kFeasibleSingle
                      : u < 0.85 ? Kind::kArbitraryDouble
                                 : Kind::kArbitrarySingle;
    const bool two = kind == Kind::kFeasibleDouble || kind == Kind::kArbitraryDouble;
    const bool right = two || uni(rng, 0.0, 1.0) < 0.5;
    ContactProblem p = geometry(rng, right, two || !right);
    if (kind == Kind::kFeasibleDouble || kind == Kind::kFeasibleSingle) {
      make_feasible(rng, p);
    } else {
      make_arbitrary(rng, p);
    }
    corpus.push_back({kind, p});
  }
  return corpus;
}

void write_corpus(const std::string& path, const std::vector<CorpusEntry>& corpus,
                  const std::vector<std::string>& comments) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error("cannot write corpus file '" + path + "'");
  out.precision(17);
  out << kHeader << "\n";
  for (const std::string& c : comments)
    out << "# " << c << "\n";
  for (const CorpusEntry& e : corpus) {
    const ContactProblem& p = e.problem;
    out << static_cast<int>(e.kind) << ' ' << p.mass;
    for (const Eigen::Vector3d* v : {&p.gravity, &p.com, &p.k_dot_desired, &p.l_dot_desired})
      for (int k = 0; k < 3; ++k)
        out << ' ' << (*v)[k];
    out << ' ' << p.weights.w_k << ' ' << p.weights.eps_f << ' ' << p.weights.eps_cop << ' '
        << p.weights.eps_tau;
    for (const FootContact& f : p.feet) {
      out << ' ' << (f.in_contact ? 1 : 0);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
          out << ' ' << f.R_WF(r, c);
      for (int k = 0; k < 3; ++k)
        out << ' ' << f.p_WF[k];
      out << ' ' << f.sole.x_min << ' ' << f.sole.x_max << ' ' << f.sole.y_min << ' '
          << f.sole.y_max << ' ' << f.safety_margin << ' ' << f.ankle_height << ' ' << f.mu << ' '
          << f.mu_torsion;
    }
    out << '\n';
  }
  if (!out) throw std::runtime_error("error writing corpus file '" + path + "'");
}

std::vector<CorpusEntry> read_corpus(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open corpus file '" + path + "'");
  std::string line;
  if (!std::getline(in, line) || line != kHeader) {
    throw std::runtime_error("'" + path + "' is not a poise contact corpus (bad header)");
  }
  std::vector<CorpusEntry> corpus;
  int line_no = 1;
  while (std::getline(in, line)) {
    ++line_no;
    if (line.empty() || line[0] == '#') continue;
    std::istringstream s(line);
    CorpusEntry e{};
    ContactProblem& p = e.problem;
    int kind = 0;
    s >> kind >> p.mass;
    for (Eigen::Vector3d* v : {&p.gravity, &p.com, &p.k_dot_desired, &p.l_dot_desired})
      for (int k = 0; k < 3; ++k)
        s >> (*v)[k];
    s >> p.weights.w_k >> p.weights.eps_f >> p.weights.eps_cop >> p.weights.eps_tau;
    for (FootContact& f : p.feet) {
      int c = 0;
      s >> c;
      f.in_contact = c != 0;
      for (int r = 0; r < 3; ++r)
        for (int cc = 0; cc < 3; ++cc)
          s >> f.R_WF(r, cc);
      for (int k = 0; k < 3; ++k)
        s >> f.p_WF[k];
      s >> f.sole.x_min >> f.sole.x_max >> f.sole.y_min >> f.sole.y_max >> f.safety_margin >>
          f.ankle_height >> f.mu >> f.mu_torsion;
    }
    if (!s || kind < 0 || kind > 5) {
      throw std::runtime_error(path + ":" + std::to_string(line_no) + ": malformed problem line");
    }
    e.kind = static_cast<Kind>(kind);
    corpus.push_back(e);
  }
  return corpus;
}

}  // namespace poise::contact::bench
