#pragma once
// The column walker of the CSV export: flattens any IDL topic sample through the generated
// msg::visit_fields() into named cells, in three modes that share one traversal so that the
// header and the rows always agree:
//   measure  records, per variable-length array (bounded by a length field) or sequence, the
//            largest length seen (the column count of that array in the file);
//   header   appends the column names (`feet[1].cop_F[0]`) for the measured widths;
//   row      appends one CSV line's cells, empty past a sample's own lengths.

#include <algorithm>
#include <charconv>
#include <cstddef>
#include <map>
#include <string>
#include <type_traits>
#include <vector>

#include <poise/reflect/traits.hpp>

#include "poise/plot/csv_export.hpp"

namespace poise::plot::detail {

enum class WalkMode { measure, header, row };

/// Column widths of the variable-length arrays of one topic, keyed by the array's path.
using Widths = std::map<std::string, std::size_t, std::less<>>;

struct Walk {
  Walk(WalkMode m, Widths& w, std::vector<std::string>* n = nullptr, std::string* l = nullptr)
      : mode(m), widths(w), names(n), line(l) {}
  WalkMode mode;
  Widths& widths;
  std::vector<std::string>* names;  // header mode
  std::string* line;                // row mode
  std::string path;                 // path of the member being walked
};

inline void append_cell(Walk& w, std::string_view text) {
  w.line->push_back(',');
  w.line->append(text);
}

template <class T>
void append_number(Walk& w, T v) {
  char buf[64];
  std::to_chars_result r;
  if constexpr (std::is_same_v<T, char> || std::is_same_v<T, signed char>) {
    r = std::to_chars(buf, buf + sizeof(buf), static_cast<int>(v));
  } else {
    r = std::to_chars(buf, buf + sizeof(buf), v);  // shortest round-trip for floating point
  }
  append_cell(w, std::string_view(buf, static_cast<std::size_t>(r.ptr - buf)));
}

template <class T>
void walk_value(Walk& w, const T& v, long long count, bool blank);

template <class S>
void walk_struct(Walk& w, const S& s, bool blank) {
  msg::visit_fields(s, [&](const reflect::FieldInfo& info, const auto& value) {
    const std::size_t mark = w.path.size();
    if (mark) w.path.push_back('.');
    w.path.append(info.name);
    walk_value(w, value, reflect::count_of(s, info.count_field), blank);
    w.path.resize(mark);
  });
}

template <class T>
void walk_value(Walk& w, const T& v, long long count, bool blank) {
  using reflect::is_array_v;
  using reflect::is_vector_v;
  if constexpr (reflect::is_struct_v<T>) {
    walk_struct(w, v, blank);
  } else if constexpr (is_array_v<T> || is_vector_v<T>) {
    const bool variable = is_vector_v<T> || count >= 0;
    std::size_t valid = v.size();
    if constexpr (is_array_v<T>) {
      if (count >= 0) valid = std::min(valid, static_cast<std::size_t>(count));
    }
    if (blank) valid = 0;
    std::size_t columns = v.size();
    if (variable) {
      auto it = w.widths.find(w.path);
      if (w.mode == WalkMode::measure) {
        if (it == w.widths.end()) it = w.widths.emplace(w.path, 0).first;
        it->second = std::max(it->second, valid);
        columns = valid;  // nested variable arrays: only the valid entries count
      } else {
        columns = it == w.widths.end() ? 0 : it->second;
      }
    }
    const typename T::value_type none{};
    const std::size_t mark = w.path.size();
    for (std::size_t i = 0; i < columns; ++i) {
      w.path.push_back('[');
      w.path.append(std::to_string(i));
      w.path.push_back(']');
      const bool empty = i >= valid;
      walk_value(w, empty && i >= v.size() ? none : v[i], -1, empty);
      w.path.resize(mark);
    }
  } else {
    if (w.mode == WalkMode::measure) return;
    if (w.mode == WalkMode::header) {
      w.names->push_back(w.path);
      return;
    }
    if (blank) {
      append_cell(w, {});
    } else if constexpr (reflect::is_fixed_string_v<T>) {
      append_cell(w, csv_quote(v.to_string()));
    } else if constexpr (reflect::is_string_v<T>) {
      append_cell(w, csv_quote(v));
    } else if constexpr (reflect::is_enum_v<T>) {
      const auto name = reflect::enum_name(v);
      if (name.empty()) {
        append_number(w, static_cast<long long>(v));
      } else {
        append_cell(w, name);
      }
    } else if constexpr (reflect::is_bool_v<T>) {
      append_cell(w, v ? "1" : "0");
    } else {
      static_assert(std::is_arithmetic_v<T>);
      append_number(w, v);
    }
  }
}

}  // namespace poise::plot::detail
