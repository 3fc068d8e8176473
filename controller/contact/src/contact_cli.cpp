// `poise contact solve [--method sequential|qp]`: one contact problem (or an array of them) as
// JSON on stdin, the solution(s) as JSON on stdout. See controller/contact/README.md.
#include <chrono>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "poise/contact/contact_json.hpp"
#include "poise/contact/contact_optimizer.hpp"
#include "poise/cli/parse.hpp"

namespace poise::contact {

namespace {

nlohmann::json solve_one(ContactOptimizer& optimizer, const nlohmann::json& in) {
  std::array<bool, kMaxFeet> present{};
  const ContactProblem problem = problem_from_json(in, &present);
  ContactSolution solution;
  const auto t0 = std::chrono::steady_clock::now();
  optimizer.solve(problem, solution);
  const auto t1 = std::chrono::steady_clock::now();
  nlohmann::json out = solution_to_json(solution, present,
                                        std::chrono::duration<double, std::micro>(t1 - t0).count());
  if (solution.status == ContactStatus::kInvalidInput) {
    const char* why = validate(problem);
    out["error"] = why != nullptr ? why : "invalid input";
  }
  return out;
}

}  // namespace

int cli_main(int argc, char** argv) {
  CLI::App app{
      "Contact-force optimiser (Lee & Goswami Sec. 3.3-3.4): admissible foot forces, CoPs "
      "and normal torques for a desired momentum rate change.",
      argv[0]};
  app.require_subcommand(1);
  CLI::App* solve = app.add_subcommand(
      "solve",
      "Read one contact problem (or a JSON array of problems) from stdin, print the solution(s) "
      "as JSON. Fields: controller/contact/README.md.");
  std::string method_name = "sequential";
  std::string input = "-";
  bool pretty = false;
  int qp_passes = 1;
  solve->add_option("--method", method_name, "sequential (paper, NNLS + BVLS) or qp (one dual QP)")
      ->check(CLI::IsMember({"sequential", "qp"}));
  solve->add_option("--input", input, "read from this file instead of stdin ('-')");
  solve->add_flag("--pretty", pretty, "indent the output");
  solve
      ->add_option("--qp-passes", qp_passes,
                   "qp only: 2 adds a refinement QP with the torsion bound linearised at the CoP")
      ->check(CLI::Range(1, 2));
  POISE_CLI_PARSE(app, argc, argv);

  nlohmann::json in;
  try {
    if (input == "-") {
      in = nlohmann::json::parse(std::cin);
    } else {
      std::ifstream file(input);
      if (!file) {
        std::cerr << argv[0] << ": error: cannot open '" << input << "'\n";
        return 2;
      }
      in = nlohmann::json::parse(file);
    }
  } catch (const nlohmann::json::parse_error& e) {
    std::cerr << argv[0] << ": error: input is not valid JSON: " << e.what() << "\n";
    return 2;
  }
  ContactOptimizer optimizer(*parse_method(method_name));
  optimizer.qp().set_torsion_passes(qp_passes);
  nlohmann::json out;
  bool any_invalid = false;
  try {
    if (in.is_array()) {
      out = nlohmann::json::array();
      for (std::size_t k = 0; k < in.size(); ++k) {
        try {
          out.push_back(solve_one(optimizer, in[k]));
        } catch (const std::invalid_argument& e) {
          throw std::invalid_argument("problem [" + std::to_string(k) + "]: " + e.what());
        }
      }
    } else {
      out = solve_one(optimizer, in);
    }
  } catch (const std::invalid_argument& e) {
    std::cerr << argv[0] << ": error: " << e.what() << "\n";
    return 2;
  }
  auto check = [&](const nlohmann::json& s) { any_invalid |= s.contains("error"); };
  if (out.is_array()) {
    for (const auto& s : out)
      check(s);
  } else {
    check(out);
  }
  std::cout << out.dump(pretty ? 2 : -1) << "\n";
  return any_invalid ? 1 : 0;
}

}  // namespace poise::contact
