#pragma once
// The local edit a critical orientation makes (docs/planning_nondirectional.md, "How much changes at a critical
// orientation"): whether a ring's change across an event is the one the event's kind makes at its point (internal to
// the nondirectional backprojection; in a header so that it can be unit tested).

#include "planning/critical.h"
#include "planning/nondirectional/region_structure.h"

namespace visco::planning::internal {

// Whether `edit` is the local change candidate c makes at its orientation (docs/planning_nondirectional.md, "How much
// changes at a critical orientation"): a free vertex crossing a static edge inserts or removes that edge between its
// two free edges; a free edge passing a point b inserts or removes a chain next to it that has b for a vertex, or the
// free edge itself next to the free edge erected at b; a free edge running along a static segment hands over from
// one end's free edge to the other's and the segment between them. Refs and points both have to agree.
bool MakesEdit(const CriticalOrientation& c, const RingEdit& e, double tol);
}  // namespace visco::planning::internal
