#pragma once
// `visco apo OBSERVATION.json`: assembly plan from observation with face-contact correction (docs/apo.md).

namespace CLI {
class App;
}

namespace visco::face_contact {

/// Adds the `apo` subcommand to the `visco` program.
void RegisterApoCommand(CLI::App& app);

}  // namespace visco::face_contact
