#pragma once
// The observation file of `visco apo` (docs/apo.md) and the result as JSON and as readable text.

#include <string>

#include "face_contact/assembly_plan.h"

namespace visco::face_contact {

/// An observation file, parsed: the observation and the options its "settings" give.
struct ApoInput {
  ApoObservation observation;
  ApoOptions options;
  std::string source;
};

/// Parse observation JSON text. @throws visco::InputError naming `source`, the JSON object and what is wrong
/// (syntax, unknown fields, unknown ids, non-rigid poses, bad models). Models are checked by PlanFromObservation.
ApoInput ParseApoObservation(const std::string& text, const std::string& source);

/// Read and parse a file. @throws visco::InputError when it cannot be read or parsed.
ApoInput LoadApoObservation(const std::string& path);

/// The result as pretty-printed JSON (docs/apo.md).
std::string ApoResultJson(const ApoInput& input, const ApoResult& result);

/// The result as text a person reads: per step the relations, the trials, the corrections and the robot's actions.
std::string ApoResultText(const ApoInput& input, const ApoResult& result);

}  // namespace visco::face_contact
