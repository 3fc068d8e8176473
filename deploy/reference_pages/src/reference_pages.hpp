#pragma once
// The page of poise-reference-pages that runs the `poise` tool: its --help and every verb's.

#include <string>

namespace poise::cli {

/// components/cli/VERBS.md: `poise --help`, then `poise VERB --help` for each verb it lists and
/// `poise VERB SUB --help` for each sub-command a verb's help lists or names that way, each in a
/// text block. Run without the caller's POISE_* environment variables (they change defaults); the
/// source and build directories in the output read <source> and <build>. Throws
/// std::runtime_error when a --help does not exit 0.
std::string verbs_page(const std::string& poise, const std::string& source_dir,
                       const std::string& build_dir, const std::string& regenerate);

}  // namespace poise::cli
