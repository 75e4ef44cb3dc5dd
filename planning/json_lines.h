#pragma once
// Internal to planning's .cc files (it includes nlohmann/json): JSON output that is readable and diff-friendly.

#include <nlohmann/json.hpp>
#include <string>

namespace visco::planning {

/// `j` (an object) with one top-level key per line, indented `key_indent` spaces, and each array value with one
/// element per line, indented `element_indent` spaces (only arrays of objects when `objects_only`; other values on
/// the key's line).
inline std::string JsonLines(const nlohmann::ordered_json& j, int key_indent, int element_indent, bool objects_only) {
  const std::string key_pad(static_cast<std::size_t>(key_indent), ' ');
  const std::string element_pad(static_cast<std::size_t>(element_indent), ' ');
  std::string out = "{";
  bool first = true;
  for (const auto& [key, value] : j.items()) {
    out += first ? "\n" : ",\n";
    first = false;
    out += key_pad + nlohmann::ordered_json(key).dump() + ": ";
    if (value.is_array() && !value.empty() && (!objects_only || value.front().is_object())) {
      out += "[";
      for (std::size_t i = 0; i < value.size(); ++i) out += (i ? ",\n" : "\n") + element_pad + value[i].dump();
      out += "\n" + key_pad + "]";
    } else {
      out += value.dump();
    }
  }
  return out + "\n}";
}

}  // namespace visco::planning
