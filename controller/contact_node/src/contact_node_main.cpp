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

int run(int argc, char** argv) {
  node::NodeOptions options;
  std::string method_name = "sequential";
  std::string priority_name = "lexicographic";
  std::string torsion_name = "friction-coupled";
  CLI::App app{"Contact-force optimiser node: contact problem k in, contact solution k out."};
  node::add_node_options(app, options, "contact");
  app.add_option("--method", method_name, "sequential (paper) or qp")
      ->check(CLI::IsMember({"sequential", "qp"}))
      ->capture_default_str();
  app.add_option("--priority", priority_name,
                 "lexicographic: the best achievable linear momentum rate, then the best angular "
                 "rate given it; weighted: the paper's eq. (21), w_k trading one for the other")
      ->check(CLI::IsMember({"lexicographic", "weighted"}))
      ->capture_default_str();
  app.add_option("--torsion-limit", torsion_name,
                 "independent: |tau_n| <= mu_torsion f_n (the paper); friction-coupled: "
                 "|tau_n| <= mu_torsion (f_n - |f_t| / mu), the twist and the tangential force "
                 "sharing one friction budget")
      ->check(CLI::IsMember({"independent", "friction-coupled"}))
      ->capture_default_str();
  app.add_option("--input-stale-ms", options.input_stale_ms,
                 "report poise/contact_problem stale (health FAULT) after this long without one")
      ->check(CLI::Range(1.0, 600000.0))
      ->capture_default_str();
  POISE_CLI_PARSE(app, argc, argv);

  const contact::Method method = *contact::parse_method(method_name);
  const contact::Priority priority = *contact::parse_priority(priority_name);
  const contact::TorsionLimit torsion = *contact::parse_torsion_limit(torsion_name);
  node::Node node(options);
  if (!options.robot.empty())  // the optimiser needs nothing of the robot: --robot is only checked
    node::resolve_robot(node, node::wait_for_robot_description(node, std::chrono::seconds(30)),
                        options.robot);
  contact::ContactOptimizer optimizer(method);
  contact::ContactProblem problem;
  contact::ContactSolution solution;

  dds::Publisher<msg::ContactSolution> solutions(node.participant());
  const dds::TypeSupport& ts = dds::TopicTraits<msg::ContactProblem>::type_support();
  Incoming in;
  msg::ContactSolution out;
  std::uint64_t bad_cdr = 0;
  const int problem_input = node.expect_input("poise/contact_problem", options.input_stale_ms);
  // One received problem: decode, validate, solve, answer. Runs on the DDS listener thread as the
  // sample arrives (no hand-off to a loop thread), under state_mutex (diagnostics: Node::serve).
  auto handle = [&](const std::vector<std::uint8_t>& bytes) noexcept {
    const std::int64_t t0 = node::now_ns();
    node.tick_begin();
    in.readable = ts.deserialize(bytes.data(), bytes.size(), &in.problem, in.why, sizeof(in.why));
    in.valid = in.readable && ts.validate(&in.problem, in.why, sizeof(in.why));
    if (!in.readable) {
      ++bad_cdr;
      node.error("unreadable contact problem (%s): not answered", in.why);
      return;
    }
    node.input_seen(problem_input, in.problem.header().tick());
    const std::int64_t t_solve = node::now_ns();
    std::int64_t lib_ns = 0;  // the library's solve alone
    const char* bad_geometry = in.valid ? contact_node::from_msg(in.problem, problem) : nullptr;
    if (bad_geometry) {
      node.error("tick %llu: invalid contact problem: %s",
                 static_cast<unsigned long long>(in.problem.header().tick()), bad_geometry);
      contact::set_safe_solution(contact::ContactStatus::kInvalidInput, solution);
    } else if (in.valid) {
      problem.weights.priority = priority;
      problem.weights.torsion = torsion;
      const std::int64_t t_lib = node::now_ns();
      optimizer.solve(problem, solution);
      lib_ns = node::now_ns() - t_lib;
      if (solution.status == contact::ContactStatus::kInvalidInput ||
          solution.status == contact::ContactStatus::kSolverFailure)
        node.error("tick %llu: %s problem (%s)",
                   static_cast<unsigned long long>(in.problem.header().tick()),
                   contact::to_string(solution.status),
                   contact::validate(problem) ? contact::validate(problem) : "numerical failure");
    } else {
      node.error("tick %llu: rejected contact problem: %s",
                 static_cast<unsigned long long>(in.problem.header().tick()), in.why);
      contact::set_safe_solution(contact::ContactStatus::kInvalidInput, solution);
    }
    const double solve_us = static_cast<double>(node::now_ns() - t_solve) * 1e-3;
    contact_node::to_msg(solution, in.problem.header(), solve_us, method, out);
    if (!reflect::validate(out)) {  // never send a non-finite answer
      node.error("tick %llu: non-finite solution replaced by the safe answer",
                 static_cast<unsigned long long>(in.problem.header().tick()));
      contact::set_safe_solution(contact::ContactStatus::kSolverFailure, solution);
      contact_node::to_msg(solution, in.problem.header(), solve_us, method, out);
    }
    node.publish(solutions, out);
    node.tick_done(in.problem.header().tick(), node::now_ns() - t0, lib_ns);
  };
  std::mutex state_mutex;
  node.wait_for_output_readers(solutions);
  dds::RawSubscriber problems(node.participant(), dds::TopicTraits<msg::ContactProblem>::topic_name,
                              dds::TopicTraits<msg::ContactProblem>::type_name,
                              dds::TopicTraits<msg::ContactProblem>::default_qos(),
                              [&](const std::vector<std::uint8_t>& bytes, const dds::SampleMeta&) {
                                std::lock_guard lock(state_mutex);
                                handle(bytes);
                              });
  node.expect_one_writer(std::string(dds::TopicTraits<msg::ContactProblem>::topic_name));
  node.serve(state_mutex);
  std::lock_guard lock(state_mutex);
  char extra[224];
  std::snprintf(extra, sizeof(extra),
                "{\"method\": \"%s\", \"priority\": \"%s\", \"torsion_limit\": \"%s\", "
                "\"unreadable_problems\": %llu}",
                contact::to_string(method), contact::to_string(priority),
                contact::to_string(torsion), static_cast<unsigned long long>(bad_cdr));
  node.write_summary(extra);
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
