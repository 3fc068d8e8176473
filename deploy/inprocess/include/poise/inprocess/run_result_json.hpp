#pragma once
// The result file of `poise run --in-process`: the distributed run's fields (deploy/launch
// run_result.cpp), with the in-process loop's figures. What has no meaning without DDS is null
// (dds, domain, dds_write_us, overhead_us) or zero by construction (the misses only a transport
// can cause: contact waits, dropped frames, samples out of sequence, references late); the
// loop's parts take the nodes' names (estimator, controller, contact; sim is the step).
#include <cstdint>
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "poise/inprocess/in_process_loop.hpp"

namespace poise::inprocess {

/// How the run was made, beside what RunResult measured.
struct RunFacts {
  std::string method;     ///< contact method run
  std::string estimator;  ///< estimator run
  bool realtime = false;  ///< --realtime: ticks paced at the control period on the wall clock
  nlohmann::json realtime_settings = nlohmann::json::object();  ///< {"poise": applied/refused}
  std::uint64_t overruns = 0;  ///< with realtime: ticks that ended after their deadline
  std::string recording;        ///< "" = not recorded
  std::string recording_error;  ///< "" = written
};

/// A RunResult alone (what the closed-loop tests and the envelope compare): the verdict and
/// the loop's measures.
nlohmann::json to_json(const RunResult& r);
/// The whole result file.
nlohmann::json to_json(const RunResult& r, const InProcessLoop& loop, const RunFacts& facts);
/// Writes `j` to `path`; std::runtime_error naming the file when that fails.
void write_result_file(const std::filesystem::path& path, const nlohmann::json& j);

}  // namespace poise::inprocess
