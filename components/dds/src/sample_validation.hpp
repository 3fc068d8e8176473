#pragma once
// Validation of incoming samples before delivery to node code: poise::reflect::validate (length
// fields within their maximum, finite numbers, valid enums, bounded strings and sequences). It
// checks without building a field path and names the field only when a sample fails.

#include <cstddef>

#include <poise/reflect/validate.hpp>

namespace poise::dds::detail {

template <class T>
bool validate_sample(const T& sample, char* why, std::size_t why_size) noexcept {
  poise::reflect::ValidationError error;
  if (poise::reflect::validate(sample, &error)) return true;
  error.format(why, why_size);
  return false;
}

}  // namespace poise::dds::detail
