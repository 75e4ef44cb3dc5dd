#pragma once
// The combinatorial structure of a region (RegionStructure, nondirectional.h) and the difference between two
// structures: which ring changed and the smallest contiguous edit that turns one into the other (internal to the
// nondirectional backprojection; in a header so that it can be unit tested).

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "planning/backprojection.h"

namespace visco::planning::internal {

// A ring's edges as "kind:ref" items, from the rotation that is least lexicographically (it names the cyclic
// sequence), after `tag`.
std::vector<std::string> RingSequence(const RegionRing& ring, const char* tag);

// The items joined by single spaces.
std::string Join(const std::vector<std::string>& v);

// One ring's change across an event: the edges of `before` from b_begin (b_count of them, wrapping) replaced by those
// of `after` from a_begin (a_count), the rest of the two rings equal.
struct RingEdit {
  const RegionRing* before = nullptr;
  const RegionRing* after = nullptr;
  size_t b_begin = 0, b_count = 0, a_begin = 0, a_count = 0;
};

inline bool SameEdge(const RegionEdge& x, const RegionEdge& y) { return x.kind == y.kind && x.ref == y.ref; }

// The smallest contiguous edit turning ring `b` into ring `a` (both cyclic), found from three anchors (edges both
// share: an anchor outside the edit gives it).
std::optional<RingEdit> SmallestEdit(const RegionRing& b, const RegionRing& a);

// The one ring of `before` and the one of `after` that differ (as cyclic sequences), when exactly one does on each
// side and the polygons they belong to are the only ones that differ.
std::optional<RingEdit> OneRingChanged(const Region& before, const Region& after,
                                       const std::vector<std::string>& s_before,
                                       const std::vector<std::string>& s_after);
}  // namespace visco::planning::internal
