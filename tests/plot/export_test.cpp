// `poise export FILE --csv`, run as a child process on MCAP files written here with
// poise::record::McapWriter: every cell of every CSV is compared with the field of the sample the
// test made (parsed back as a number, enum name or string), column widths of length-bounded
// arrays, times, decode failures, foreign schemas, and bad input (not MCAP, cut short, unknown
// topic).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdlib>
#include <random>
#include <variant>

#include <poise/reflect/fill.hpp>

#include "plot_test_support.hpp"

namespace poise::plot_test {
namespace {

// The value a cell must hold, derived from the sample (not from the exporter's code).
using Expected = std::variant<double, long long, unsigned long long, bool, std::string /*enum*/,
                              Cell /*string: quoted text*/>;

template <class T>
void expect_value(const T& v, const std::string& path, long long count,
                  std::map<std::string, Expected>& out);

template <class S>
void expect_struct(const S& s, const std::string& path, std::map<std::string, Expected>& out) {
  msg::visit_fields(s, [&](const msg::FieldInfo& info, const auto& value) {
    expect_value(value, path.empty() ? std::string(info.name) : path + "." + std::string(info.name),
                 reflect::count_of(s, info.count_field), out);
  });
}

template <class T>
void expect_value(const T& v, const std::string& path, long long count,
                  std::map<std::string, Expected>& out) {
  if constexpr (reflect::is_struct_v<T>) {
    expect_struct(v, path, out);
  } else if constexpr (reflect::is_array_v<T> || reflect::is_vector_v<T>) {
    std::size_t n = v.size();
    if (count >= 0) n = std::min<std::size_t>(n, static_cast<std::size_t>(count));
    for (std::size_t i = 0; i < n; ++i)
      expect_value(v[i], path + "[" + std::to_string(i) + "]", -1, out);
  } else if constexpr (reflect::is_fixed_string_v<T>) {
    out[path] = Cell{v.to_string(), true};
  } else if constexpr (reflect::is_string_v<T>) {
    out[path] = Cell{v, true};
  } else if constexpr (reflect::is_enum_v<T>) {
    out[path] = std::string(msg::EnumTraits<T>::names.at(static_cast<std::size_t>(v)));
  } else if constexpr (reflect::is_bool_v<T>) {
    out[path] = v;
  } else if constexpr (std::is_floating_point_v<T>) {
    out[path] = static_cast<double>(v);
  } else if constexpr (std::is_signed_v<T>) {
    out[path] = static_cast<long long>(v);
  } else {
    out[path] = static_cast<unsigned long long>(v);
  }
}

/// "" when the cell holds the expected value, else what differs.
std::string check_cell(const Cell& cell, const Expected& e) {
  auto bad = [&](const std::string& want) { return "cell '" + cell.text + "', want " + want; };
  if (const auto* d = std::get_if<double>(&e)) {
    char* end = nullptr;
    const double got = std::strtod(cell.text.c_str(), &end);
    if (cell.quoted || cell.text.empty() || *end != '\0' || !(got == *d)) {
      char buf[64];
      std::snprintf(buf, sizeof(buf), "%.17g", *d);
      return bad(buf);
    }
  } else if (const auto* i = std::get_if<long long>(&e)) {
    char* end = nullptr;
    const long long got = std::strtoll(cell.text.c_str(), &end, 10);
    if (cell.quoted || cell.text.empty() || *end != '\0' || got != *i)
      return bad(std::to_string(*i));
  } else if (const auto* u = std::get_if<unsigned long long>(&e)) {
    char* end = nullptr;
    const unsigned long long got = std::strtoull(cell.text.c_str(), &end, 10);
    if (cell.quoted || cell.text.empty() || *end != '\0' || got != *u || cell.text[0] == '-')
      return bad(std::to_string(*u));
  } else if (const auto* b = std::get_if<bool>(&e)) {
    if (cell.quoted || cell.text != (*b ? "1" : "0")) return bad(*b ? "1" : "0");
  } else if (const auto* name = std::get_if<std::string>(&e)) {
    if (cell.text != *name) return bad(*name);
  } else {
    const Cell& s = std::get<Cell>(e);
    if (!cell.quoted || cell.text != s.text) return bad("the quoted string '" + s.text + "'");
  }
  return {};
}

struct Logged {
  std::uint64_t log_time, publish_time;
};

/// Checks a topic's CSV against the samples written, in order. Returns the header; adds the
/// number of field cells compared to `*compared`.
template <class T>
std::vector<std::string> check_csv(const std::string& path, const std::vector<T>& samples,
                                   const std::vector<Logged>& times, std::uint64_t origin,
                                   std::size_t* compared = nullptr) {
  const auto rows = read_csv(path);
  EXPECT_EQ(rows.size(), samples.size() + 1) << path;
  if (rows.empty()) return {};
  std::vector<std::string> header;
  for (const auto& c : rows[0])
    header.push_back(c.text);
  EXPECT_GE(header.size(), 3u);
  EXPECT_EQ(header[0], "log_time_s");
  EXPECT_EQ(header[1], "publish_time_s");
  std::map<std::string, std::size_t> index;
  for (std::size_t i = 0; i < header.size(); ++i) {
    EXPECT_TRUE(index.emplace(header[i], i).second) << path << ": column twice: " << header[i];
  }
  std::size_t failures = 0;
  for (std::size_t r = 0; r + 1 < rows.size() && r < samples.size(); ++r) {
    const CsvRow& row = rows[r + 1];
    SCOPED_TRACE(path + " row " + std::to_string(r + 1));
    if (row.size() != header.size()) {
      ADD_FAILURE() << row.size() << " cells, header has " << header.size();
      return header;
    }
    // Times: seconds since the earliest log time of the file.
    EXPECT_NEAR(std::strtod(row[0].text.c_str(), nullptr),
                static_cast<double>(times[r].log_time - origin) * 1e-9, 1e-9);
    if (times[r].publish_time == 0) {
      EXPECT_EQ(row[1].text, "");
    } else {
      EXPECT_NEAR(std::strtod(row[1].text.c_str(), nullptr),
                  (static_cast<double>(times[r].publish_time) - static_cast<double>(origin)) * 1e-9,
                  1e-6);
    }
    std::map<std::string, Expected> expected;
    expect_struct(samples[r], "", expected);
    for (const auto& [name, value] : expected) {
      const auto it = index.find(name);
      if (it == index.end()) {
        ADD_FAILURE() << "no column " << name;
        if (++failures > 20) return header;
        continue;
      }
      const std::string why = check_cell(row[it->second], value);
      if (compared) ++*compared;
      if (!why.empty()) {
        ADD_FAILURE() << name << ": " << why;
        if (++failures > 20) return header;
      }
    }
    // Every other column is an entry past this row's length: empty.
    for (std::size_t c = 2; c < header.size(); ++c) {
      if (!expected.count(header[c]) && (!row[c].text.empty() || row[c].quoted)) {
        ADD_FAILURE() << header[c] << ": '" << row[c].text << "' past the row's length";
        if (++failures > 20) return header;
      }
    }
  }
  return header;
}

std::size_t count_columns(const std::vector<std::string>& header, const std::string& prefix) {
  std::size_t n = 0;
  for (const auto& h : header)
    n += h.rfind(prefix, 0) == 0 ? 1 : 0;
  return n;
}

// The cell check must be able to fail: one ulp, a lost quote, a wrong enum name, a stray cell.
TEST(CellCheck, FlagsWhatDiffers) {
  EXPECT_EQ(check_cell({"0.1", false}, Expected{0.1}), "");
  EXPECT_NE(check_cell({"0.10000000000000002", false}, Expected{0.1}), "");
  EXPECT_NE(check_cell({"0.1", true}, Expected{0.1}), "");
  EXPECT_NE(check_cell({"", false}, Expected{0.0}), "");
  EXPECT_NE(check_cell({"18446744073709551615", false}, Expected{18446744073709551614ULL}), "");
  EXPECT_NE(check_cell({"-1", false}, Expected{1LL}), "");
  EXPECT_NE(check_cell({"true", false}, Expected{true}), "");
  EXPECT_NE(check_cell({"CONTACT_OK", false}, Expected{std::string("CONTACT_PROJECTED")}), "");
  EXPECT_NE(check_cell({"abc", false}, Expected{Cell{"abc", true}}), "");
  EXPECT_EQ(check_cell({"a,\"b\"", true}, Expected{Cell{"a,\"b\"", true}}), "");
}

constexpr std::uint64_t kT0 = 1'760'000'000'123'456'789ULL;  // log time of the first message

class ExportTest : public ::testing::Test {
 protected:
  ScratchDir dir;
};

TEST_F(ExportTest, EveryCellEqualsTheSampleField) {
  std::mt19937_64 rng(20240607);
  std::vector<msg::State> states(25);
  std::vector<msg::ContactSolution> solutions(25);
  std::vector<msg::Diagnostics> diagnostics(6);
  std::vector<msg::RobotDescription> descriptions(2);
  std::vector<msg::Disturbance> disturbances(3);
  std::vector<msg::GroundTruth> truths(10);
  for (auto& s : states)
    reflect::fill_random(s, rng);
  states[3].joint_count(0);  // a row with no q at all
  states[4].joint_count(64);
  states[4].com_W({-0.0, 4.9e-324, 1e300});  // signed zero, denormal, huge
  for (auto& s : solutions)
    reflect::fill_random(s, rng);
  for (auto& d : diagnostics)
    reflect::fill_random(d, rng);
  diagnostics[0].last_error("say \"hi\", then\nbye");
  diagnostics[1].node("");
  for (auto& d : descriptions)
    reflect::fill_random(d, rng);
  descriptions[0].urdf("<robot name=\"r,1\">\r\n  <link name=\"a\"/>\n</robot>\n");
  descriptions[0].joint_names({"hip, left", "knee \"L\"", ""});
  descriptions[1].joint_names({"a"});
  for (auto& d : disturbances)
    reflect::fill_random(d, rng);
  for (auto& g : truths)
    reflect::fill_random(g, rng);

  // Interleaved in log time as a recorder would write them; one message without publish time.
  const std::string file = dir / "run.mcap";
  std::vector<Logged> t_state, t_solution, t_diag, t_desc, t_dist, t_truth;
  {
    Recording rec(file, 16 * 1024);  // several chunks
    std::uint64_t t = kT0;
    auto next = [&](std::vector<Logged>& times, bool no_publish = false) {
      t += 1'000'003;
      times.push_back({t, no_publish ? 0 : t - 250'000});
      return times.back();
    };
    for (std::size_t i = 0; i < descriptions.size(); ++i) {
      const auto l = next(t_desc);
      rec.write(descriptions[i], l.log_time, l.publish_time);
    }
    for (std::size_t i = 0; i < states.size(); ++i) {
      auto l = next(t_state, i == 7);
      rec.write(states[i], l.log_time, l.publish_time);
      l = next(t_solution);
      rec.write(solutions[i], l.log_time, l.publish_time);
      if (i < diagnostics.size()) {
        l = next(t_diag);
        rec.write(diagnostics[i], l.log_time, l.publish_time);
      }
      if (i < disturbances.size()) {
        l = next(t_dist);
        rec.write(disturbances[i], l.log_time, l.publish_time);
      }
      if (i < truths.size()) {
        l = next(t_truth);
        rec.write(truths[i], l.log_time, l.publish_time);
      }
    }
    rec.close();
  }
  const std::uint64_t origin = t_desc.front().log_time;

  const std::string out = dir / "csv";
  const PoiseRun r = run_poise({"export", file, "--csv", "-o", out});
  ASSERT_EQ(r.code, 0) << r.output;

  std::size_t compared = 0;
  const auto state_header = check_csv(out + "/poise_state.csv", states, t_state, origin, &compared);
  check_csv(out + "/poise_contact_solution.csv", solutions, t_solution, origin, &compared);
  check_csv(out + "/poise_diagnostics.csv", diagnostics, t_diag, origin, &compared);
  const auto desc_header =
      check_csv(out + "/poise_robot_description.csv", descriptions, t_desc, origin, &compared);
  check_csv(out + "/poise_disturbance.csv", disturbances, t_dist, origin, &compared);
  const auto truth_header =
      check_csv(out + "/poise_ground_truth.csv", truths, t_truth, origin, &compared);
  // Every field of every sample was compared (State alone has > 100 fields past its arrays).
  std::size_t fields = 0;
  auto count_fields = [&](const auto& samples) {
    for (const auto& s : samples) {
      std::map<std::string, Expected> e;
      expect_struct(s, "", e);
      fields += e.size();
    }
  };
  count_fields(states);
  count_fields(solutions);
  count_fields(diagnostics);
  count_fields(descriptions);
  count_fields(disturbances);
  count_fields(truths);
  EXPECT_EQ(compared, fields);
  EXPECT_GT(compared, 25u * 100u);
  std::printf("compared %zu cells with the samples' fields\n", compared);

  // Hand-written spot checks, independent of the reflection: names, widths, a few values.
  unsigned max_joints = 0;
  for (const auto& s : states)
    max_joints = std::max<unsigned>(max_joints, s.joint_count());
  EXPECT_EQ(count_columns(state_header, "q["), max_joints);
  EXPECT_EQ(count_columns(state_header, "qd["), max_joints);
  EXPECT_EQ(count_columns(state_header, "com_W["), 3u);
  ASSERT_GE(state_header.size(), 4u);
  EXPECT_EQ(state_header[2], "header.tick");
  EXPECT_EQ(state_header[3], "header.stamp_ns");
  EXPECT_EQ(count_columns(desc_header, "joint_names["), 3u);
  unsigned max_other = 0;
  for (const auto& g : truths)
    max_other = std::max<unsigned>(max_other, g.other_contact_count());
  EXPECT_EQ(count_columns(truth_header, "other_contact_links["), max_other);

  const auto state_rows = read_csv(out + "/poise_state.csv");
  const auto solution_rows = read_csv(out + "/poise_contact_solution.csv");
  auto col = [](const std::vector<CsvRow>& rows, const std::string& name) {
    for (std::size_t i = 0; i < rows[0].size(); ++i)
      if (rows[0][i].text == name) return i;
    ADD_FAILURE() << "no column " << name;
    return std::size_t{0};
  };
  for (std::size_t i = 0; i < states.size(); ++i) {
    const auto& row = state_rows.at(i + 1);
    EXPECT_EQ(std::strtoull(row[col(state_rows, "header.tick")].text.c_str(), nullptr, 10),
              states[i].header().tick());
    EXPECT_EQ(std::strtod(row[col(state_rows, "com_W[2]")].text.c_str(), nullptr),
              states[i].com_W()[2]);
    EXPECT_EQ(std::strtod(row[col(state_rows, "feet[1].pose_W.position[0]")].text.c_str(), nullptr),
              states[i].feet()[1].pose_W().position()[0]);
    if (states[i].joint_count() > 0) {
      EXPECT_EQ(std::strtod(row[col(state_rows, "q[0]")].text.c_str(), nullptr), states[i].q()[0]);
    } else {
      EXPECT_EQ(row[col(state_rows, "q[0]")].text, "");
    }
  }
  EXPECT_EQ(state_rows.at(5)[col(state_rows, "com_W[0]")].text, "-0");
  for (std::size_t i = 0; i < solutions.size(); ++i) {
    const auto& row = solution_rows.at(i + 1);
    EXPECT_EQ(std::strtod(row[col(solution_rows, "feet[1].cop_F[0]")].text.c_str(), nullptr),
              solutions[i].feet()[1].cop_F()[0]);
    EXPECT_EQ(row[col(solution_rows, "status")].text,
              msg::EnumTraits<msg::ContactStatus>::names.at(solutions[i].status()));
  }
  const auto diag_rows = read_csv(out + "/poise_diagnostics.csv");
  EXPECT_EQ(diag_rows.at(1)[col(diag_rows, "last_error")].text, "say \"hi\", then\nbye");
  EXPECT_TRUE(diag_rows.at(2)[col(diag_rows, "node")].quoted);
  EXPECT_EQ(diag_rows.at(2)[col(diag_rows, "node")].text, "");
}

TEST_F(ExportTest, MessagesThatDoNotDecodeAreCountedAndNamed) {
  std::mt19937_64 rng(7);
  std::vector<msg::State> states(3);
  for (auto& s : states)
    reflect::fill_random(s, rng);
  const std::string file = dir / "bad.mcap";
  std::vector<Logged> times;
  {
    Recording rec(file);
    std::uint64_t t = kT0;
    for (std::size_t i = 0; i < states.size(); ++i) {
      rec.write(states[i], t, t);
      times.push_back({t, t});
      t += 1'000'000;
      if (i == 1) {
        // A State cut after 10 bytes of body: does not decode.
        auto bytes = cdr_bytes(states[i]);
        bytes.resize(14);
        rec.write_raw(rec.channel<msg::State>(), t, t, bytes);
        t += 1'000'000;
      }
    }
    rec.close();
  }
  const std::string out = dir / "csv";
  const PoiseRun r = run_poise({"export", file, "--csv", "-o", out});
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("poise/state: 1 message(s) do not decode"), std::string::npos)
      << r.output;
  check_csv(out + "/poise_state.csv", states, times, kT0);
}

TEST_F(ExportTest, ForeignSchemasAreSkippedWithAMessage) {
  std::mt19937_64 rng(8);
  msg::State state;
  reflect::fill_random(state, rng);
  const std::string file = dir / "mixed.mcap";
  {
    Recording rec(file);
    rec.write(state, kT0, kT0);
    const auto sid =
        rec.writer().add_schema("foreign::Thing", "omgidl", "struct Thing { long x; };");
    const auto cid = rec.writer().add_channel(sid, "other/thing", "cdr");
    rec.write_raw(cid, kT0 + 1, kT0 + 1, {0, 1, 0, 0, 1, 2, 3, 4});
    rec.close();
  }
  const std::string out = dir / "csv";
  const PoiseRun r = run_poise({"export", file, "--csv", "-o", out});
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_NE(r.output.find("skipped other/thing"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("not a Poise topic type"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(out + "/poise_state.csv"));
  EXPECT_FALSE(fs::exists(out + "/other_thing.csv"));
}

TEST_F(ExportTest, DefaultDirectoryAndTopicSelection) {
  std::mt19937_64 rng(9);
  msg::State state;
  msg::ContactSolution solution;
  reflect::fill_random(state, rng);
  reflect::fill_random(solution, rng);
  const std::string file = dir / "sel.mcap";
  {
    Recording rec(file);
    rec.write(state, kT0, kT0);
    rec.write(solution, kT0 + 5, kT0 + 5);
    rec.close();
  }
  const PoiseRun r = run_poise({"export", file, "--csv", "--topics", "poise/contact_solution"});
  EXPECT_EQ(r.code, 0) << r.output;
  EXPECT_TRUE(fs::exists(dir / "sel_csv/poise_contact_solution.csv"));
  EXPECT_FALSE(fs::exists(dir / "sel_csv/poise_state.csv"));
}

TEST_F(ExportTest, NotMcapIsAnError) {
  const std::string file = dir / "notes.mcap";
  std::ofstream(file) << "log_time,value\n1,2\n";
  const PoiseRun r = run_poise({"export", file, "--csv", "-o", dir / "csv"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("not an MCAP file"), std::string::npos) << r.output;
  EXPECT_FALSE(fs::exists(dir / "csv"));
}

TEST_F(ExportTest, MissingFileAndMissingFormatAreErrors) {
  PoiseRun r = run_poise({"export", dir / "nope.mcap", "--csv"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("no such file"), std::string::npos) << r.output;
  r = run_poise({"export", dir / "nope.mcap"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("--csv"), std::string::npos) << r.output;
}

TEST_F(ExportTest, UnknownTopicIsAnError) {
  std::mt19937_64 rng(10);
  msg::State state;
  reflect::fill_random(state, rng);
  const std::string file = dir / "one.mcap";
  {
    Recording rec(file);
    rec.write(state, kT0, kT0);
    rec.close();
  }
  const PoiseRun r =
      run_poise({"export", file, "--csv", "-o", dir / "csv", "--topics", "poise/nope"});
  EXPECT_EQ(r.code, 2) << r.output;
  EXPECT_NE(r.output.find("'poise/nope' is not in the recording"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("poise/state"), std::string::npos) << r.output;  // what it holds
  EXPECT_FALSE(fs::exists(dir / "csv/poise_state.csv"));
}

TEST_F(ExportTest, TruncatedFileExportsWhatItHoldsAndSaysSo) {
  std::mt19937_64 rng(11);
  std::vector<msg::State> states(200);
  for (auto& s : states)
    reflect::fill_random(s, rng);
  const std::string whole = dir / "whole.mcap";
  std::vector<Logged> times;
  {
    Recording rec(whole, 8 * 1024);  // many chunks: a cut keeps the earlier ones
    for (std::size_t i = 0; i < states.size(); ++i) {
      times.push_back({kT0 + i * 1'000'000, kT0 + i * 1'000'000});
      rec.write(states[i], times.back().log_time, times.back().publish_time);
    }
    rec.close();
  }
  const std::string cut = dir / "cut.mcap";
  {
    std::ifstream in(whole, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    std::ofstream(cut, std::ios::binary) << bytes.substr(0, bytes.size() * 6 / 10);
  }
  const std::string out = dir / "csv";
  const PoiseRun r = run_poise({"export", cut, "--csv", "-o", out});
  EXPECT_EQ(r.code, 1) << r.output;
  EXPECT_NE(r.output.find("is incomplete"), std::string::npos) << r.output;
  const auto rows = read_csv(out + "/poise_state.csv");
  ASSERT_GT(rows.size(), 20u);
  ASSERT_LT(rows.size(), states.size());
  // What it holds is the first messages, exactly.
  const std::size_t held = rows.size() - 1;
  check_csv(out + "/poise_state.csv",
            std::vector<msg::State>(states.begin(), states.begin() + static_cast<long>(held)),
            times, kT0);
}

}  // namespace
}  // namespace poise::plot_test
