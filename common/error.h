#pragma once
// The ways visco reports failure to users (docs/formats.md): bad input exits 2 with
// "visco: FILE: OBJECT: what is wrong"; a job that ran and failed exits 1; one whose input was partly damaged or
// missing, and whose answer covers only the rest, exits 3.

#include <stdexcept>
#include <string>

namespace visco {

/// Bad user input: a file, and the object inside it, that is wrong. `visco` prints
/// "visco: <file>: <object>: <what>" and exits 2. Throw it wherever user input is validated.
class InputError : public std::runtime_error {
 public:
  /// @param file the file (or "command line") that holds the bad input.
  /// @param object the object within it, e.g. "obstacles[2].polygon" (may be empty).
  /// @param what what is wrong, in words a user understands.
  InputError(std::string file, std::string object, const std::string& what)
      : std::runtime_error(Compose(file, object, what)), file_(std::move(file)), object_(std::move(object)) {}

  const std::string& file() const { return file_; }
  const std::string& object() const { return object_; }

 private:
  static std::string Compose(const std::string& file, const std::string& object, const std::string& what) {
    std::string message = file;
    if (!object.empty()) message += ": " + object;
    return message + ": " + what;
  }
  std::string file_;
  std::string object_;
};

/// The job ran and failed (for example: no plan exists). `visco` prints "visco: <what>" and exits 1.
class JobFailed : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// The job ran, and what it could check passed, but part of its input was damaged or missing, so the answer covers
/// only part of it (for example: `visco replay --check` on a log with skipped bytes). `visco` prints "visco: <what>"
/// and exits 3.
class Incomplete : public JobFailed {
 public:
  using JobFailed::JobFailed;
};

}  // namespace visco
