#include "poise/contact/contact_optimizer.hpp"

namespace poise::contact {

const char* to_string(Method m) {
  return m == Method::kQp ? "qp" : "sequential";
}

std::optional<Method> parse_method(std::string_view name) {
  if (name == "sequential") return Method::kSequential;
  if (name == "qp") return Method::kQp;
  return std::nullopt;
}

}  // namespace poise::contact
