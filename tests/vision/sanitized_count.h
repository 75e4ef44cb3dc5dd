#pragma once
// Seeded workloads that shrink under AddressSanitizer (the CI's `scripts/test asan`), where rendering, detection and
// refinement run several times slower: the same seeds and checks on the first `sanitized` items there, all `full`
// items otherwise.

namespace visco::vision::test_world {

constexpr int SanitizedCount(int full, int sanitized) {
#if defined(__SANITIZE_ADDRESS__)
  (void)full;
  return sanitized;
#else
  (void)sanitized;
  return full;
#endif
}

}  // namespace visco::vision::test_world
