#pragma once
// The ray choice of B_vcθ(G) (internal to the directional backprojection; in a header so that it can be unit tested):
// which set of active CVC rays VcEnlargedBackprojection relies on, chosen by sweeping candidate sets and comparing
// their regions exactly (backprojection.h, VcEnlargedBackprojection, says how each method chooses).

#include <CGAL/Polygon_2.h>
#include <CGAL/Polygon_set_2.h>

#include <vector>

#include "planning/backprojection/plane_sweep.h"

namespace visco::planning::internal {

using ExactPolygon = CGAL::Polygon_2<K>;
using PolygonSet = CGAL::Polygon_set_2<K>;

// The simple loops of a ring. A ring may touch itself at a vertex (two parts of the region meeting at a point, or a
// hole touching the outer boundary), which CGAL's polygon sets reject as a precondition (and which a release build
// would take silently and wrongly): the ring is cut at each repeated vertex into loops that are each simple. A loop
// that encloses nothing (an edge walked out and back) is dropped.
std::vector<ExactPolygon> SimpleLoops(const std::vector<P2>& ring);

// The region of `rings` as an exact polygon set: the points inside an odd number of the rings' loops (outer
// boundaries, holes, and islands inside holes alike).
PolygonSet ToPolygonSet(const std::vector<ExactRing>& rings);
bool LargerArea(const SweepResult& a, const SweepResult& b);

// True if the region of `rings` contains `set` (exact polygon difference).
bool ContainsSet(const PolygonSet& set, const std::vector<ExactRing>& rings);

// Sweeps `set`; adopts its region as the current one if it is strictly larger and contains the current one (B_θ ⊆
// B_vcθ, and every earlier claim stays valid). True if adopted.
bool AdoptIfLarger(const BackprojectionProblem& problem, SweepFrame& frame, const std::vector<int>& set,
                   SweepResult& current, PolygonSet& current_set, int& sweeps);

// Greedy choice: single candidates in order, then pairs of rejected ones; a set is kept only if its region contains
// the current region and is strictly larger.
std::vector<int> GreedySelection(const BackprojectionProblem& problem, SweepFrame& frame,
                                 const std::vector<int>& candidates, SweepResult& current, int& sweeps);

// Whether adding ray c to `active` cannot enlarge the region, decided without a sweep: every piece of c complies to
// an open end (the bounds, the camera end, where the camera loses the vertex) and meets neither the goal nor an active
// ray on the way. A trajectory that reaches such a piece, however it reaches it, complies to that end (a reliable ray:
// every velocity in the cone projects onto it the same way) and fails; so with c active every point keeps or loses
// its place in the region, none is added. Conservative: a piece whose box meets a goal's box counts as meeting it.
bool LeadsOnlyToOpenEnds(const BackprojectionProblem& problem, int c, const std::vector<int>& active);

// How far outside the region (a fraction of the bounds' diagonal) a closed end must lie for LandsOnlyOutside: a
// million times the sweep's snapping of ray ends onto CB (1e-9), far above the region's rounding.
constexpr double kLandingMargin = 1e-6;

// Whether adding ray c to `active` cannot enlarge `region` (the region swept with `active`), decided without a sweep:
// as LeadsOnlyToOpenEnds, but a piece may also end on CB at a point p outside the region's closure by more than
// kLandingMargin. A motion that reaches c complies down to p and moves on from p under the contact rules. c lies
// upstream of p (motions progress along θ), so from p on a motion never meets that piece again; if it meets another
// piece of c it complies to that piece's end, and the piece furthest along θ is met by no motion from another piece's
// end. So, from the last piece back, every motion from p is one the region without c has too, and if all of them
// reached the goal, so would those from free points beside p (they reach CB or pass p close by, with the same fates
// wherever the region's boundary does not pass through p), and p would lie in the region's closure. Hence some
// motion from each end fails, every trajectory that reaches c can be made to fail, and no point joins the region.
// Checked against the choice without the skip on random scenes (VcSoundnessProperty).
bool LandsOnlyOutside(const BackprojectionProblem& problem, int c, const std::vector<int>& active,
                      const Region& region);

// Track-pruned choice (the default): start with every reliable candidate active and drop, sweep after sweep, the rays
// with a piece of bad track (complying down from there fails: it ends on a sticking edge, an open end, or switches
// to a ray that fails), until every active ray leads to good places along its whole length (at most k + 1 sweeps;
// rays that only help together stay, since their tracks are computed with each other active). That set's region is
// kept if it contains B_θ(G) (exact polygon difference; otherwise the start is the empty set). Then each dropped ray
// is tried once more on its own, in id order, and kept if the region grows and still contains the current one (a ray
// that only leads to open ends is not tried: LeadsOnlyToOpenEnds, nor one that lands only outside the region:
// LandsOnlyOutside).
// Last, every active ray the region does not need is dropped. At most 3k + 1 sweeps in all, against 2^k for the exact
// search.
std::vector<int> TrackSelection(const BackprojectionProblem& problem, SweepFrame& frame,
                                const std::vector<int>& candidates, SweepResult& current, int& sweeps,
                                bool skip_open_ended, bool skip_outside_landings);

// Exact choice: every subset of the candidates, by size, then lexicographically (so that the first set reaching the
// best area is the smallest, then the first by id). A subset's region is checked for containing B_θ(G) only when
// its area beats the best so far (the check is a polygon difference; the sweep is the unavoidable cost).
std::vector<int> ExactSelection(const BackprojectionProblem& problem, SweepFrame& frame,
                                const std::vector<int>& candidates, SweepResult& best, int& sweeps);

}  // namespace visco::planning::internal
