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

const char* to_string(Priority p) {
  return p == Priority::kWeighted ? "weighted" : "lexicographic";
}

std::optional<Priority> parse_priority(std::string_view name) {
  if (name == "lexicographic") return Priority::kLexicographic;
  if (name == "weighted") return Priority::kWeighted;
  return std::nullopt;
}

std::optional<TorsionLimit> parse_torsion_limit(std::string_view name) {
  if (name == "independent") return TorsionLimit::kIndependent;
  if (name == "friction-coupled") return TorsionLimit::kFrictionCoupled;
  return std::nullopt;
}

}  // namespace poise::contact
