#include "app/paths.h"

#include <unistd.h>

#include <array>

#include "common/error.h"

namespace visco::app {

std::filesystem::path ExecutableDir() {
  std::array<char, 4096> buffer{};
  const ssize_t length = ::readlink("/proc/self/exe", buffer.data(), buffer.size() - 1);
  if (length <= 0) return std::filesystem::current_path();
  return std::filesystem::path(std::string(buffer.data(), static_cast<size_t>(length))).parent_path();
}

std::filesystem::path FindDataFile(const std::string& relative) {
  const std::filesystem::path candidate = ExecutableDir().parent_path() / relative;
  if (std::filesystem::exists(candidate)) return candidate;
  throw JobFailed("cannot find " + relative + " (looked for " + candidate.string() +
                  "); build the project or install it");
}

}  // namespace visco::app
