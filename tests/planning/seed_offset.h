#pragma once
// VISCO_SEED_OFFSET=N shifts every seed of the random scene generators (random_scenes.h, random_vc_scenes.h) by N, so
// the property tests run on scenes nobody has run them on before. Failure messages give the unshifted seeds: rerun
// with the same offset (docs/development.md, "Property tests on other seeds").

#include <cstdint>
#include <cstdlib>

namespace visco::planning::testing {

inline std::uint64_t SeedOffset() {
  const char* env = std::getenv("VISCO_SEED_OFFSET");
  return env != nullptr ? std::strtoull(env, nullptr, 10) : 0;
}

// The tests' checks that they are not vacuous (enough enlarged regions, candidates, accepted seeds) are sized for the
// seeds CI runs; on shifted seeds the counts are printed but not required (soundness is required everywhere).
inline bool DesignedSeeds() { return SeedOffset() == 0; }

}  // namespace visco::planning::testing
