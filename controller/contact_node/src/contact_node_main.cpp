// poise-contact: the contact-force optimiser (paper Sec. 3.3-3.4) as a DDS node.
//
// ------------------------------------------------------------------------------------------------
// Contract
//   subscribes  poise/contact_problem   ContactProblem   1 kHz  reliable, keep-last 1
//   publishes   poise/contact_solution  ContactSolution  one per problem, header (tick) copied
//                                                         reliable, keep-last 1
//               poise/diagnostics       Diagnostics      ~10 Hz best-effort, keep-last 1
//   method      --method sequential (paper: NNLS + BVLS) | qp (one Goldfarb-Idnani QP)
//   priority    --priority lexicographic (linear momentum first, strictly) | weighted (eq. (21)
//               as written); not in the problem message, so `poise run` passes the controller
//               configuration's contact.priority here
//   torsion     --torsion-limit friction-coupled (|tau_n| <= mu_t (f_n - |f_t| / mu)) |
//               independent (the paper's |tau_n| <= mu_t f_n); likewise from contact.torsion_limit
//   bad input   a problem with a non-finite number, a bad length or an inconsistent geometry is
//               answered with status CONTACT_INVALID_INPUT and the library's safe answer (every
//               wrench zero), and counted (diagnostics errors / rejected_samples). A sample too
//               malformed to read its tick is counted and not answered.
//   never       publishes a non-finite number (checked before publishing).
// ------------------------------------------------------------------------------------------------
// The problem topic is read as raw CDR so that a problem failing validation still yields its tick
// (the typed subscriber would drop it silently for the sender). Each problem is solved and
// answered on the DDS listener thread as it arrives (no wake-up of a loop thread per tick); the
// main thread only publishes the diagnostics (Node::serve).
#include <CLI/CLI.hpp>

#include <cstdio>
#include <cstring>
#include <exception>
#include <memory>
#include <mutex>

#include "poise/contact_node/contact_messages.hpp"
#include "poise/node/node.hpp"
#include "poise/node/robot_description.hpp"
#include "poise/cli/parse.hpp"

namespace {

using namespace poise;

/// One received problem, decoded.
struct Incoming {
  msg::ContactProblem problem;
  bool readable = false;  ///< CDR decoded (the header is meaningful)
  bool valid = false;     ///< passed the IDL validation (finite, lengths)
  char why[200] = {};
};

/// The command line.
struct Options {
  node::NodeOptions node;
  std::string method_name = "sequential";
  std::string priority_name = "lexicographic";
  std::string torsion_name = "friction-coupled";
};

/// Parses the command line into `o`. Returns the exit status when the command line ends the run
/// (0 after --help, 2 for a usage error), else -1.
int parse_options(int argc, char** argv, Options& o) {
  CLI::App app{"Contact-force optimiser node: contact problem k in, contact solution k out."};
  node::add_node_options(app, o.node, "contact");
  app.add_option("--method", o.method_name, "sequential (paper) or qp")
      ->check(CLI::IsMember({"sequential", "qp"}))
      ->capture_default_str();
  app.add_option("--priority", o.priority_name,
                 "lexicographic: the best achievable linear momentum rate, then the best angular "
                 "rate given it; weighted: the paper's eq. (21), w_k trading one for the other")
      ->check(CLI::IsMember({"lexicographic", "weighted"}))
      ->capture_default_str();
  app.add_option("--torsion-limit", o.torsion_name,
                 "independent: |tau_n| <= mu_torsion f_n (the paper); friction-coupled: "
                 "|tau_n| <= mu_torsion (f_n - |f_t| / mu), the twist and the tangential force "
                 "sharing one friction budget")
      ->check(CLI::IsMember({"independent", "friction-coupled"}))
      ->capture_default_str();
  app.add_option("--input-stale-ms", o.node.input_stale_ms,
                 "report poise/contact_problem stale (health FAULT) after this long without one")
      ->check(CLI::Range(1.0, 600000.0))
      ->capture_default_str();
  POISE_CLI_PARSE(app, argc, argv);
  return -1;
}

/// --robot checked against the robot description (the optimiser needs nothing of the robot).
/// Returns whether there was one to check.
bool check_robot(node::Node& node, const std::string& robot) {
  if (robot.empty()) return false;
  node::resolve_robot(node, node::wait_for_robot_description(node, std::chrono::seconds(30)),
                      robot);
  return true;
}

/// The contact optimiser node: its endpoints, the optimiser and its buffers. Each problem is
/// handled on the DDS listener thread as it arrives, under `state_mutex_` (diagnostics:
/// Node::serve).
class ContactNode {
 public:
  explicit ContactNode(const Options& o);
  /// Answers the problems until shutdown; the diagnostics meanwhile.
  void serve();
  /// The summary file's extra figures.
  void write_summary();

 private:
  // ---- one problem (allocation-free) --------------------------------------------------------
  void handle(const std::vector<std::uint8_t>& bytes) noexcept;
  bool decode(const std::vector<std::uint8_t>& bytes) noexcept;
  std::int64_t solve_or_refuse() noexcept;
  void answer(double solve_us) noexcept;

  const contact::Method method_;
  const contact::Priority priority_;
  const contact::TorsionLimit torsion_;
  node::Node node_;
  [[maybe_unused]] const bool robot_checked_;  // before the optimiser's endpoints
  contact::ContactOptimizer optimizer_;
  contact::ContactProblem problem_;
  contact::ContactSolution solution_;

  dds::Publisher<msg::ContactSolution> solutions_;
  const dds::TypeSupport& ts_;
  Incoming in_;
  msg::ContactSolution out_;
  std::uint64_t bad_cdr_ = 0;
  const int problem_input_;
  std::mutex state_mutex_;
  std::unique_ptr<dds::RawSubscriber> problems_;
};

ContactNode::ContactNode(const Options& o)
    : method_(*contact::parse_method(o.method_name)),
      priority_(*contact::parse_priority(o.priority_name)),
      torsion_(*contact::parse_torsion_limit(o.torsion_name)),
      node_(o.node),
      robot_checked_(check_robot(node_, o.node.robot)),
      optimizer_(method_),
      solutions_(node_.participant()),
      ts_(dds::TopicTraits<msg::ContactProblem>::type_support()),
      problem_input_(node_.expect_input("poise/contact_problem", o.node.input_stale_ms)) {}

// One received problem: decode, validate, solve, answer. Runs on the DDS listener thread as the
// sample arrives (no hand-off to a loop thread), under state_mutex_ (diagnostics: Node::serve).
void ContactNode::handle(const std::vector<std::uint8_t>& bytes) noexcept {
  const std::int64_t t0 = node::now_ns();
  node_.tick_begin();
  if (!decode(bytes)) return;
  node_.input_seen(problem_input_, in_.problem.header().tick());
  const std::int64_t t_solve = node::now_ns();
  const std::int64_t lib_ns = solve_or_refuse();  // the library's solve alone
  const double solve_us = static_cast<double>(node::now_ns() - t_solve) * 1e-3;
  answer(solve_us);
  node_.tick_done(in_.problem.header().tick(), node::now_ns() - t0, lib_ns);
}

// The CDR sample into in_, validated. False when it is too malformed to read its tick (counted,
// not answered).
bool ContactNode::decode(const std::vector<std::uint8_t>& bytes) noexcept {
  in_.readable =
      ts_.deserialize(bytes.data(), bytes.size(), &in_.problem, in_.why, sizeof(in_.why));
  in_.valid = in_.readable && ts_.validate(&in_.problem, in_.why, sizeof(in_.why));
  if (!in_.readable) {
    ++bad_cdr_;
    node_.error("unreadable contact problem (%s): not answered", in_.why);
    return false;
  }
  return true;
}

// solution_ for in_: the optimiser's, or the safe answer (every wrench zero) for a problem that
// fails validation. Returns the library's solve time [ns] (0 when it did not solve).
std::int64_t ContactNode::solve_or_refuse() noexcept {
  std::int64_t lib_ns = 0;
  const char* bad_geometry = in_.valid ? contact_node::from_msg(in_.problem, problem_) : nullptr;
  if (bad_geometry) {
    node_.error("tick %llu: invalid contact problem: %s",
                static_cast<unsigned long long>(in_.problem.header().tick()), bad_geometry);
    contact::set_safe_solution(contact::ContactStatus::kInvalidInput, solution_);
  } else if (in_.valid) {
    problem_.weights.priority = priority_;
    problem_.weights.torsion = torsion_;
    const std::int64_t t_lib = node::now_ns();
    optimizer_.solve(problem_, solution_);
    lib_ns = node::now_ns() - t_lib;
    if (solution_.status == contact::ContactStatus::kInvalidInput ||
        solution_.status == contact::ContactStatus::kSolverFailure)
      node_.error("tick %llu: %s problem (%s)",
                  static_cast<unsigned long long>(in_.problem.header().tick()),
                  contact::to_string(solution_.status),
                  contact::validate(problem_) ? contact::validate(problem_) : "numerical failure");
  } else {
    node_.error("tick %llu: rejected contact problem: %s",
                static_cast<unsigned long long>(in_.problem.header().tick()), in_.why);
    contact::set_safe_solution(contact::ContactStatus::kInvalidInput, solution_);
  }
  return lib_ns;
}

// solution_ out with the problem's header; never a non-finite number.
void ContactNode::answer(double solve_us) noexcept {
  contact_node::to_msg(solution_, in_.problem.header(), solve_us, method_, out_);
  if (!reflect::validate(out_)) {  // never send a non-finite answer
    node_.error("tick %llu: non-finite solution replaced by the safe answer",
                static_cast<unsigned long long>(in_.problem.header().tick()));
    contact::set_safe_solution(contact::ContactStatus::kSolverFailure, solution_);
    contact_node::to_msg(solution_, in_.problem.header(), solve_us, method_, out_);
  }
  node_.publish(solutions_, out_);
}

void ContactNode::serve() {
  node_.wait_for_output_readers(solutions_);
  problems_ = std::make_unique<dds::RawSubscriber>(
      node_.participant(), dds::TopicTraits<msg::ContactProblem>::topic_name,
      dds::TopicTraits<msg::ContactProblem>::type_name,
      dds::TopicTraits<msg::ContactProblem>::default_qos(),
      [this](const std::vector<std::uint8_t>& bytes, const dds::SampleMeta&) {
        std::lock_guard lock(state_mutex_);
        handle(bytes);
      });
  node_.expect_one_writer(std::string(dds::TopicTraits<msg::ContactProblem>::topic_name));
  node_.serve(state_mutex_);
}

void ContactNode::write_summary() {
  std::lock_guard lock(state_mutex_);
  char extra[224];
  std::snprintf(extra, sizeof(extra),
                "{\"method\": \"%s\", \"priority\": \"%s\", \"torsion_limit\": \"%s\", "
                "\"unreadable_problems\": %llu}",
                contact::to_string(method_), contact::to_string(priority_),
                contact::to_string(torsion_), static_cast<unsigned long long>(bad_cdr_));
  node_.write_summary(extra);
}

int run(int argc, char** argv) {
  Options o;
  if (const int status = parse_options(argc, argv, o); status >= 0) return status;
  ContactNode contact(o);
  contact.serve();
  contact.write_summary();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "poise-contact: %s\n", e.what());
    return 2;
  }
}
