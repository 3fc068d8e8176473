// Text of the generated reference pages (CONFIG.md, SCHEMA.md: deploy/reference_pages): the
// shortest number that reads back the same, and a markdown table cell. Header-only.
#pragma once

#include <charconv>
#include <string>
#include <string_view>

namespace poise::cli {

/// The shortest text that reads back as `v` ("0.85", "1e-07").
inline std::string number_text(double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  return std::string(buf, r.ptr);
}

/// `s` as a markdown table cell: a '|' would end it, so it is escaped.
inline std::string markdown_cell(std::string_view s) {
  std::string out;
  for (const char ch : s) {
    if (ch == '|') out += '\\';
    out += ch;
  }
  return out;
}

}  // namespace poise::cli
