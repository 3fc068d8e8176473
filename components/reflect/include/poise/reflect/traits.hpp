#pragma once
// Type classification used by the walkers over IDL samples.

#include <array>
#include <cstddef>
#include <string>
#include <type_traits>
#include <vector>

#include <fastrtps/utils/fixed_size_string.hpp>
#include <poise/msg/reflection_gen.hpp>

namespace poise::reflect {

using msg::FieldInfo;

template <class T>
inline constexpr bool is_struct_v = msg::IsIdlStruct<std::remove_const_t<T>>::value;

template <class T>
struct IsStdArray : std::false_type {};
template <class T, std::size_t N>
struct IsStdArray<std::array<T, N>> : std::true_type {};
template <class T>
inline constexpr bool is_array_v = IsStdArray<std::remove_const_t<T>>::value;

/// std::array of float or double.
template <class T>
struct IsFloatArray : std::false_type {};
template <class T, std::size_t N>
struct IsFloatArray<std::array<T, N>> : std::is_floating_point<T> {};
template <class T>
inline constexpr bool is_float_array_v = IsFloatArray<std::remove_const_t<T>>::value;

template <class T>
struct IsStdVector : std::false_type {};
template <class T, class A>
struct IsStdVector<std::vector<T, A>> : std::true_type {};
template <class T>
inline constexpr bool is_vector_v = IsStdVector<std::remove_const_t<T>>::value;

template <class T>
struct IsFixedString : std::false_type {};
template <std::size_t N>
struct IsFixedString<eprosima::fastrtps::fixed_string<N>> : std::true_type {};

/// Bounded IDL strings (string<N>) are fastddsgen fixed_string<N>: no allocation, capacity N.
template <class T>
inline constexpr bool is_fixed_string_v = IsFixedString<std::remove_const_t<T>>::value;

/// Any IDL string: unbounded std::string or bounded fixed_string<N>.
template <class T>
inline constexpr bool is_string_v =
    std::is_same_v<std::remove_const_t<T>, std::string> || is_fixed_string_v<T>;

template <class T>
inline constexpr bool is_enum_v = std::is_enum_v<std::remove_const_t<T>>;

template <class T>
inline constexpr bool is_bool_v = std::is_same_v<std::remove_const_t<T>, bool>;

template <class T>
inline constexpr bool is_number_v = std::is_arithmetic_v<std::remove_const_t<T>> && !is_bool_v<T>;

/// Name of an enumerator, or "" when the value is out of range.
template <class E>
std::string_view enum_name(E value) {
  const auto& names = msg::EnumTraits<std::remove_const_t<E>>::names;
  const auto i = static_cast<std::size_t>(value);
  return i < names.size() ? names[i] : std::string_view{};
}

/// Value of the count member named `count_field` in struct `s`, or -1 if there is none.
template <class S>
long long count_of(const S& s, std::string_view count_field) {
  long long result = -1;
  if (count_field.empty()) return result;
  msg::visit_fields(s, [&](const FieldInfo& info, const auto& value) {
    using V = std::remove_cvref_t<decltype(value)>;
    if constexpr (std::is_integral_v<V> && !std::is_same_v<V, bool>) {
      if (info.name == count_field) result = static_cast<long long>(value);
    }
  });
  return result;
}

}  // namespace poise::reflect
