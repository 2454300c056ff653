#include "mvtwin/core/outcome.h"

namespace mvtwin {

const char* outcome_name(Outcome o) {
  switch (o) {
    case Outcome::kConverged:
      return "converged";
    case Outcome::kInvertedElement:
      return "inverted_element";
    case Outcome::kLeafletCrossing:
      return "leaflet_crossing";
    case Outcome::kLinearSolver:
      return "linear_solver";
    case Outcome::kNonFiniteState:
      return "non_finite_state";
    case Outcome::kInvalidInput:
      return "invalid_input";
  }
  return "unknown";
}

std::optional<Outcome> parse_outcome(const std::string& name) {
  for (int k = 0; k < kNumOutcomes; ++k) {
    const auto o = static_cast<Outcome>(k);
    if (name == outcome_name(o)) return o;
  }
  return std::nullopt;
}

}  // namespace mvtwin
