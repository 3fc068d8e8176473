// Nothing the docs point at is missing: in every markdown file of the source tree, each relative
// link target ([text](path), without its #fragment) and each path written from the tree's top
// (controller/..., deploy/..., in backticks or not) exists. A path followed by a placeholder
// (`deploy/scenarios/platforms_*.yaml`, `results/<scenario>.json`) is a pattern, not a path.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <set>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

const fs::path kRoot = POISE_SOURCE_DIR;

/// The markdown files of the source tree (not the build trees, results or hidden directories).
std::vector<fs::path> markdown_files() {
  std::vector<fs::path> out;
  for (auto it = fs::recursive_directory_iterator(kRoot); it != fs::recursive_directory_iterator();
       ++it) {
    const std::string name = it->path().filename().string();
    if (it->is_directory() && (name.starts_with(".") || name.starts_with("build") ||
                               name == "results" || name == "node_modules")) {
      it.disable_recursion_pending();
      continue;
    }
    if (it->is_regular_file() && it->path().extension() == ".md") out.push_back(it->path());
  }
  return out;
}

/// The top-level directories of the tree: a path that starts with one is a path of the tree.
std::set<std::string> top_directories() {
  std::set<std::string> tops;
  for (const auto& e : fs::directory_iterator(kRoot)) {
    const std::string name = e.path().filename().string();
    if (e.is_directory() && !name.starts_with(".") && !name.starts_with("build") &&
        name != "results")
      tops.insert(name);
  }
  return tops;
}

std::string read(const fs::path& p) {
  std::ifstream in(p);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

}  // namespace

TEST(DocLinks, EveryRelativeLinkAndTreePathInTheDocsExists) {
  const std::vector<fs::path> docs = markdown_files();
  ASSERT_GT(docs.size(), 10u) << "the docs were not found under " << kRoot;
  std::string tops;
  for (const auto& t : top_directories()) tops += (tops.empty() ? "" : "|") + t;
  const std::regex link(R"(\]\(([^)\s]+)\))");
  const std::regex tree_path("(^|[^\\w./-])((?:" + tops + ")/[\\w./-]*[\\w/])");
  int links = 0, paths = 0;
  for (const fs::path& doc : docs) {
    const std::string text = read(doc);
    const std::string name = fs::relative(doc, kRoot).string();
    for (std::sregex_iterator it(text.begin(), text.end(), link), end; it != end; ++it) {
      std::string target = (*it)[1];
      if (target.starts_with("http:") || target.starts_with("https:") ||
          target.starts_with("mailto:") || target.starts_with("#"))
        continue;
      target = target.substr(0, target.find('#'));
      ++links;
      EXPECT_TRUE(fs::exists(doc.parent_path() / target))
          << name << ": the link target '" << target << "' does not exist";
    }
    for (std::sregex_iterator it(text.begin(), text.end(), tree_path), end; it != end; ++it) {
      const std::string path = (*it)[2];
      const auto after = static_cast<std::size_t>(it->position(2) + it->length(2));
      if (after < text.size() && std::string("*<{$").find(text[after]) != std::string::npos)
        continue;  // a pattern
      ++paths;
      EXPECT_TRUE(fs::exists(kRoot / path)) << name << ": '" << path << "' is not in the tree";
    }
  }
  std::printf("[links] %zu markdown files: %d relative links, %d tree paths, all present\n",
              docs.size(), links, paths);
  EXPECT_GT(paths, 100) << "the path pattern no longer finds the docs' paths";
}
