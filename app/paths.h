#pragma once
// Where the running `visco` finds the files it ships (the LCM jar, the default scene, ...): next to the program in
// the build tree (build/bin/../share/...) or in the install prefix (<prefix>/bin/../share/...).

#include <filesystem>
#include <string>

namespace visco::app {

/// Directory holding the running executable. Not real-time safe.
std::filesystem::path ExecutableDir();

/// Resolves `relative` (e.g. "share/java/visco_lcmtypes.jar") against the program's prefix.
/// @throws visco::JobFailed naming the paths tried if the file is missing.
std::filesystem::path FindDataFile(const std::string& relative);

}  // namespace visco::app
