#pragma once
// Which scene a strategy or a rays file was made for (docs/formats.md, "scene_digest"): the planner writes the digest
// of the scene it read, and `visco run` compares it with the digest of the scene it is given, so that a strategy is
// never executed in a scene it was not planned for. The digest is of the scene's JSON in canonical form (parsed, then
// written compactly with keys sorted: nlohmann::json's dump()), so that spacing and key order do not matter.

#include <cstdint>
#include <string>
#include <string_view>

namespace visco {

/// The 64-bit FNV-1a hash of `canonical_json` as 16 lower-case hex digits. A check against mix-ups, not against
/// forgery. Not real-time safe (allocates the string).
inline std::string SceneDigest(std::string_view canonical_json) {
  std::uint64_t h = 0xcbf29ce484222325ULL;
  for (const char c : canonical_json) {
    h ^= static_cast<unsigned char>(c);
    h *= 0x100000001b3ULL;
  }
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out(16, '0');
  for (int i = 15; i >= 0; --i, h >>= 4) out[static_cast<std::size_t>(i)] = kHex[h & 0xf];
  return out;
}

}  // namespace visco
