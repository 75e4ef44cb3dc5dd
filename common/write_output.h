#pragma once
// Writes a command's text output to stdout (empty path) or to a file, the `--out FILE` convention of every
// subcommand.

#include <cstdio>
#include <fstream>
#include <string>

#include "common/error.h"

namespace visco {

/// Writes `text` plus a newline to `path`, or to stdout when `path` is empty. Not real-time safe.
/// @throws visco::InputError naming the path if the file cannot be written.
inline void WriteTextOutput(const std::string& text, const std::string& path) {
  if (path.empty()) {
    std::fwrite(text.data(), 1, text.size(), stdout);
    std::fputc('\n', stdout);
    return;
  }
  std::ofstream file(path);
  file << text << "\n";
  if (!file) throw InputError(path, "", "cannot write the output file");
}

}  // namespace visco
