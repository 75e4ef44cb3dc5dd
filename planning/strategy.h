#pragma once
// Motion strategies by backchaining preimages (LMT; Fox & Hutchinson §IV-A, §VIII; docs/planning_strategy.md).
//
// A strategy is a list of steps in execution order; step k is (θ, active CVC rays, termination). The planner works
// backwards from the goal kernel (the goal eroded by ε_p: the sensed position is then surely in the goal):
//   * the last step ends by goal termination; its preimage is B_vcθ(kernel);
//   * an earlier step ends by visual guarded termination on a CVC ray r (`vc`): the motion stops when the named CM
//     vertex crosses the VC line. The position along the ray is not observed, so the step's target is a piece of r
//     (a thin strip around it, `kVcStripHalfWidth`) that lies inside the next step's preimage, and the rest of r is
//     forbidden (BackprojectionProblem::forbidden: reaching it first would end the step outside): the step's
//     preimage is the set from which every motion reaches r first on that piece;
//   * an earlier step ends by contact termination (`contact`): the motion sticks on a face of CB (an edge where the
//     whole velocity cone lies inside the friction cone) or in a concave corner of CB (inside the convex hull of the
//     two faces' friction cones). θ is restricted to the interval where the feature sticks; the target is a thin
//     region at the feature (`kContactDepth`), and every place where the motion can stick after entering it (the
//     piece of the face, or the corner's faces within `end_radius`) lies inside the next step's preimage.
// θ is never sampled: each preimage comes from the nondirectional backprojection of its target (nondirectional.h),
// and the θ-intervals where the previous target fits come from IntervalsContaining (bounded by critical and
// R-critical orientations). Strategies with fewer steps win, then the larger margin (the distance of the start
// region's boundary to the first preimage's), then θ and ray ids (deterministic).

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "planning/backprojection.h"
#include "planning/scene.h"
#include "planning/svg.h"

namespace visco {
class motion_strategy_t;
}

namespace visco::planning {

class CSpace;
struct VcRays;

/// Half-width of the strip standing for "somewhere on the ray" (metres): the robot stops within this of the VC line
/// (the servo's tracking error and the event's latency at the commanded speed must stay below it).
inline constexpr double kVcStripHalfWidth = 0.01;

/// A thin rectangle around the segment [a, b] ("somewhere on this piece of the ray"), `half_width` to either side;
/// vertices a − n, b − n, b + n, a + n named `REF.v[k]`, edges `REF.e[k]`: a visual guarded step's target and the
/// forbidden rest of its ray.
NamedPolygon Strip(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double half_width, const std::string& ref);

/// The same with the strip's sides parallel to `direction` instead of b − a: consecutive pieces of one segment given
/// its direction share their corners exactly (with each piece's own b − a they differ by rounding, and the regions
/// planned against them carry edges 10⁻¹⁶ long there).
NamedPolygon Strip(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double half_width, const std::string& ref,
                   const Eigen::Vector2d& direction);

/// Depth of the target region at a contact feature (metres): a motion that enters it sticks within the feature's piece
/// (the piece is shrunk by the lateral drift the friction cone allows over this depth).
inline constexpr double kContactDepth = 0.01;

enum class Termination : std::uint8_t { kGoal, kVisualGuarded, kContact };
/// "goal", "vc", "contact" (docs/formats.md).
const char* TerminationName(Termination t);

struct StrategyStep {
  double theta = 0.0;  ///< commanded direction (radians)
  std::vector<std::string> active_rays;
  Termination terminate = Termination::kGoal;
  std::string terminate_ref;  ///< vc: the CVC ray id; contact: the CB face's or corner's provenance
  /// Where the step is guaranteed to succeed from (B_vcθ of its target with the active rays).
  Region preimage;
  /// Where it ends: the goal kernel (goal), or a strip around the piece of the ray where it must end (vc).
  std::vector<NamedPolygon> target;
  /// vc: strips around all of the ray's free segments (reaching any stops the step; only `target` succeeds).
  std::vector<NamedPolygon> triggers;
  /// vc: the ends of that piece of the ray; contact: of the piece of the face where it sticks (a corner: both are the
  /// corner).
  Eigen::Vector2d end_a{0, 0}, end_b{0, 0};
  /// Where the step can end: within this distance of the segment [end_a, end_b] (vc: the strip's half-width; contact
  /// on a face: 0, on the face itself; in a corner: on its faces within this of the corner).
  double end_radius = 0.0;
  /// contact: the θ-interval where the feature sticks (the step's interval lies inside it).
  double sticks_lo = 0.0, sticks_hi = 0.0;
  /// The θ-interval in which this step's θ was chosen (every θ in it works) and the margin there: the least distance
  /// from the boundary of what must fit (the start region, or the previous step's target) to the preimage's.
  double interval_lo = 0.0, interval_hi = 0.0;
  double margin = 0.0;
  /// What the step guarantees, in words (for the JSON and the docs).
  std::string guarantee;
};

struct Strategy {
  bool feasible = false;
  std::vector<StrategyStep> steps;  ///< execution order
  /// When infeasible: why, and what would help (the largest share of the start region one step covers, at which θ,
  /// whether a camera would help).
  std::string reason;
  double best_coverage = 0.0;  ///< share of the start region inside the best one-step preimage (0..1)
  double best_theta = 0.0;
  std::int64_t nondirectional = 0;  ///< nondirectional backprojections computed
  /// What the search explored: child targets computed (each one nondirectional backprojection) and the levels
  /// (steps) it reached; the most memory (resident set, MiB) it saw; whether it stopped at the memory limit.
  std::int64_t children = 0;
  int levels = 1;
  double peak_memory_mib = 0.0;
  bool memory_limit_reached = false;
  /// Where the time went (wall clock): the goal's nondirectional backprojection, the children's summed over the
  /// threads, and the slowest child; the VC-enlarged backprojections (sweeps) the goal's and the children's ran.
  double goal_seconds = 0.0, children_seconds = 0.0, slowest_child_seconds = 0.0;
  std::int64_t goal_sweeps = 0, children_sweeps = 0;
};

/// Where the search is, for a progress line: the level (the number of steps of the strategies it now tries), the
/// child targets of that level done and in all, the seconds since the start and an estimate of those left for the
/// level (0 when unknown).
struct PlanProgress {
  int level = 1;
  int max_steps = 1;
  std::int64_t done = 0, total = 0;
  double elapsed_s = 0.0;
  double level_left_s = 0.0;
};

/// The process's resident memory now (MiB; 0 where unknown).
double ResidentMemoryMiB();

/// How the multi-step search treats the child targets of a level (docs/planning_strategy.md, "Multi-step search:
/// time and memory").
enum class SearchMode : std::uint8_t {
  /// The default: the children are computed `threads` at a time (each nondirectional backprojection on one thread),
  /// a child keeps only what the next level reads (its slices' B_θ regions, without provenance strings), and the
  /// children of the last level keep nothing (only whether the start region fits).
  kLean,
  /// The search before: one child at a time (each nondirectional backprojection on `threads` threads), every child
  /// keeping its whole nondirectional backprojection. The same strategies; kept to compare.
  kBaseline,
};

struct PlanOptions {
  int max_steps = 3;
  bool kernel_only = false;  ///< goal-terminated steps only (no visual guarded subgoals): one step or none
  bool use_camera = true;    ///< false: plan as if the scene had no camera (no CVC rays)
  int threads = 1;
  /// Contact features (faces and corners of CB) tried per target, the longest pieces first.
  int max_contact_features = 8;
  /// At most this many nondirectional backprojections (each a few seconds); the reason says when it was reached.
  int max_nondirectional = 60;
  /// Stop the search (no strategy, the reason says what was explored) when the process's resident memory exceeds
  /// this many MiB; 0: no limit.
  double max_memory_mib = 0.0;
  /// How the memory limit reads the memory in use (MiB; empty: the process's resident memory). For the tests.
  std::function<double()> resident_memory_mib;
  SearchMode search = SearchMode::kLean;
  std::function<void(double)> progress;
  /// Called from the calling thread after each child target and at each level's start.
  std::function<void(const PlanProgress&)> search_progress;
};

/// Why a scene has no strategy when its goal kernel is empty: `visco plan`'s reason, `visco vcrays`'s warning.
inline constexpr char kEmptyGoalKernel[] =
    "goal: the goal kernel is empty (the goal is narrower than twice the position uncertainty): no strategy can "
    "recognise that it is in the goal";

/// Plans a strategy from the scene's start region to its goal; an infeasible one (with its reason) when there is none,
/// the goal kernel being empty included. @throws InputError (via the scene) if the scene has no start region.
Strategy PlanStrategy(const Scene& scene, const PlanOptions& options = {});

/// The contract's `visco plan` JSON: {"feasible", "scene", "steps": [{"theta_deg", "active_rays", "terminate":
/// {"kind", "ref"}, "preimage": REGION, "guarantee", "interval_deg": [lo, hi], "margin"}], "reason"}.
/// `speed` (m/s) is the commanded speed `visco run` uses (an extension of the contract's fields, as are the per-step
/// "timeout_s": three times the bounds' diagonal at that speed, plus 10 s).
std::string StrategyToJson(const Scene& scene, const Strategy& strategy, double speed = 0.25);

/// The time-out of every step at commanded speed `speed` (m/s): three times the bounds' diagonal at that speed, plus
/// 10 s, in whole seconds (the JSON's and the LCM message's "timeout_s").
double StepTimeout(const Scene& scene, double speed);

/// The strategy as the LCM message `visco run` also accepts (speed in m/s, the JSON's time-outs).
motion_strategy_t StrategyToLcm(const Scene& scene, const Strategy& strategy, double speed);

/// The nested preimages of the steps (Fig. 13 style): the start region, each preimage, its commanded direction, the
/// rays used and the goal.
std::string StrategyToSvg(const Scene& scene, const CSpace& cspace, const Strategy& strategy);

/// The same drawing onto a canvas of the scene's bounds (for pictures drawn over the plan, e.g. `visco demo`'s).
void DrawStrategy(SvgCanvas& canvas, const Scene& scene, const CSpace& cspace, const Strategy& strategy);
/// The legend of DrawStrategy's picture, in words (rows for SvgCanvas::Legend).
std::vector<std::vector<SvgCanvas::LegendItem>> StrategyLegend(const Strategy& strategy);

/// Result of simulating a strategy (the motion model of docs/semantics.md with adversarial velocities).
struct StrategyCheck {
  int starts = 0;                     ///< sampled start configurations (interior and boundary of R)
  int successes = 0;                  ///< reached the goal kernel after the last step
  std::vector<std::string> failures;  ///< "start (x, y): step k: outcome", at most 20
};

/// Runs the strategy from `samples` seeded start configurations in the start region (half on its boundary) with the
/// standard battery of adversaries per step, chaining each step's end into the next. One start in three complies
/// exactly; the others run the scene's tracking error (uncertainty.vc_tracking) to the left or right of a ray's line
/// (MotionWorld::ray_landing_offset).
StrategyCheck CheckStrategy(const Scene& scene, const CSpace& cspace, const VcRays& rays, const Strategy& strategy,
                            int samples, std::uint64_t seed);

}  // namespace visco::planning
