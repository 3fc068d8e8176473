#pragma once
// Readable text of a sample, for `poise topic echo`: one "name: value" per line, nested structs
// indented, short numeric arrays on one line.

#include <cstdio>
#include <string>

#include "poise/reflect/json.hpp"

namespace poise::reflect {

namespace detail {

inline void print_json(const Json& j, std::string& out, int indent) {
  const std::string pad(static_cast<std::size_t>(indent) * 2, ' ');
  for (auto it = j.begin(); it != j.end(); ++it) {
    const Json& v = it.value();
    if (v.is_object()) {
      out += pad + it.key() + ":\n";
      print_json(v, out, indent + 1);
    } else if (v.is_array() && !v.empty() && v.front().is_object()) {
      for (std::size_t i = 0; i < v.size(); ++i) {
        out += pad + it.key() + "[" + std::to_string(i) + "]:\n";
        print_json(v[i], out, indent + 1);
      }
    } else if (v.is_array()) {
      out += pad + it.key() + ": [";
      for (std::size_t i = 0; i < v.size(); ++i) {
        if (i) out += ", ";
        if (v[i].is_number_float()) {
          char buf[32];
          std::snprintf(buf, sizeof(buf), "%.6g", v[i].get<double>());
          out += buf;
        } else {
          out += v[i].dump();
        }
      }
      out += "]\n";
    } else if (v.is_number_float()) {
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%.9g", v.get<double>());
      out += pad + it.key() + ": " + buf + "\n";
    } else if (v.is_string()) {
      const auto s = v.get<std::string>();
      out += pad + it.key() + ": " +
             (s.size() > 200 ? v.dump().substr(0, 200) + "...\"" : v.dump()) + "\n";
    } else {
      out += pad + it.key() + ": " + v.dump() + "\n";
    }
  }
}

}  // namespace detail

/// Multi-line readable text of a sample.
template <class T>
std::string to_text(const T& sample) {
  std::string out;
  detail::print_json(to_json(sample), out, 0);
  return out;
}

}  // namespace poise::reflect
