#pragma once
#include <optional>
#include <string>

namespace mvtwin {

/// How a simulation (or one of its steps) ended: a typed reason, kept beside the free-text
/// message that names the element, node or time. Studies and tests classify failures by it,
/// never by searching the message.
enum class Outcome {
  kConverged,        ///< ran to the end
  kInvertedElement,  ///< an element inverted and halving the step did not mend it
  kLeafletCrossing,  ///< continuous collision detection: a node would pass through a leaflet
  kLinearSolver,     ///< the step's linear system could not be solved
  kNonFiniteState,   ///< a position or velocity became NaN or infinite
  kInvalidInput,     ///< options, parameters or anatomy that cannot be modelled (mvtwin::Error)
};
inline constexpr int kNumOutcomes = 6;

/// Snake-case name, as written to result files: "converged", "inverted_element", ...
const char* outcome_name(Outcome o);
/// The outcome of a name given by outcome_name(); nullopt for an unknown name.
std::optional<Outcome> parse_outcome(const std::string& name);

}  // namespace mvtwin
