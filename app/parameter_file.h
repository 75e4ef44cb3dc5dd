#pragma once
// Parameter files: every option of every command can come from a JSON file, `--config FILE`, so that a run is
// repeated from files rather than from thirty flags (docs/formats.md, "Parameter files"). The file names the
// command it configures and holds its options by their long names:
//   {"driver": {"world": "world.json", "start": [2, 6], "seed": 3, "truth-hz": 200}}
// Flags given on the command line win over the file; an unknown command or option is an error (exit 2) that names
// the file and the key. CLI11 reads the file (its config mechanism, with a JSON format instead of its TOML).

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace visco::app {

/// Adds `--config FILE` to `app` (accepted before or after the subcommand) and the JSON format.
void EnableParameterFiles(CLI::App& app);

/// The parameter file of `command` run with `args` (its options: `--name value...` and bare flags; the tokens
/// before the first `--name`, the positionals, are not part of it): the JSON text that `--config` reads back to the
/// same options. Values that read as numbers are written as numbers, the rest as strings.
std::string ParameterFileJson(const std::string& command, const std::vector<std::string>& args);

}  // namespace visco::app
