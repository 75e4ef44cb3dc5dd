#pragma once
// The one implementation of docs/semantics.md's motion model: a translating point (the robot's reference point) in
// C = R^2 among polygonal C-obstacles, under the generalised damper with Coulomb friction, a velocity chosen
// adversarially inside the control uncertainty cone, active CVC rays as frictionless two-sided walls, a bounds
// rectangle (leaving it fails) and a goal region (entering it succeeds).
//
// Two layers:
//   * MotionModel: the immutable world and the physics. AdvanceToEvent/Advance move a MotionState under a given
//     actual velocity (the step-wise API the simulated robot uses); the contact rules are exposed as predicates
//     (Sticks, IsStickingEdge, ResolveAt) so that the planner decides sticking exactly as the simulator does.
//   * Simulate(): a whole trajectory for a commanded direction θ against an Adversary that picks the actual
//     direction inside the cone and may switch it at any time (extreme, random-switching and greedy adversaries).
//
// Numerics (documented tolerances, biased towards failure where that keeps planners sound):
//   * lengths: a point within length_tolerance() (1e-9 times the bounds diagonal, at least 1e-12) of a segment is
//     on it; positions are snapped onto the edge being slid along and onto vertices within that tolerance;
//   * sticking: the angle between v and -n is computed with atan2(|v x n|, -v.n) and compared with φ + kAngleTol
//     (1e-12 rad), so an angle of exactly φ sticks even after rounding;
//   * bounds: a configuration up to length_tolerance() outside the rectangle still counts as inside;
//   * goal: a configuration within length_tolerance() of the closed goal has reached it.

#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace visco {

/// Angular slack of the sticking test (radians): an angle up to φ + kAngleTol between v and -n sticks.
inline constexpr double kStickAngleTolerance = 1e-12;

/// Everything the motion model needs, as plain geometry in C-space (metres).
struct MotionWorld {
  /// C-obstacles (CBᵢ = Bᵢ ⊕ (−A)), simple polygons in either orientation; they may overlap.
  std::vector<std::vector<Eigen::Vector2d>> obstacles;
  /// Goal regions (closed simple polygons, either orientation), e.g. the goal or its kernel (possibly several parts).
  std::vector<std::vector<Eigen::Vector2d>> goal;
  /// Allowed configurations: the closed rectangle [bounds_min, bounds_max].
  Eigen::Vector2d bounds_min{0.0, 0.0};
  Eigen::Vector2d bounds_max{0.0, 0.0};
  /// Free-space segments of the active CVC rays (frictionless two-sided walls).
  std::vector<std::array<Eigen::Vector2d, 2>> active_rays;
  /// Per active ray, per end: true where the end is open (the bounds clip the ray there, or it is the camera end).
  /// The servo keeps the CM vertex on the VC line past such an end, so reaching it fails (kOpenRayEnd). Empty, or
  /// shorter than active_rays: the remaining ends are on C-obstacles (contact rules apply there).
  std::vector<std::array<bool, 2>> active_ray_open_ends;
  /// Friction cone half-angle φ in radians, in [0, π/2).
  double friction_cone = 0.0;
  /// The servo's tracking error as a signed offset (metres, left of the direction of motion positive): a motion that
  /// complies down an active ray runs this far beside the ray's line and meets CB where that parallel line enters it
  /// (beside the ray, or near an end on a C-obstacle rather than at it), where compliance ends and the contact rules
  /// take over. 0: exact compliance. Tests run ±δ to check what the planner's BackprojectionProblem::ray_tracking_error
  /// promises.
  double ray_landing_offset = 0.0;
};

/// What the reference point is doing.
enum class MotionMode : std::uint8_t {
  kFree,     ///< moving in free space with the actual velocity
  kSliding,  ///< sliding along C-obstacle edge `edge`
  kOnRay,    ///< complying to active ray `ray`
  kStopped,  ///< stuck (friction) or stopped at a vertex/ray: no motion under the current velocity
};

/// Identifies an edge of the motion world: edge `edge` of obstacle `obstacle` runs from vertex `edge` to `edge + 1`
/// of the normalised (counter-clockwise) polygon.
struct EdgeId {
  int obstacle = -1;
  int edge = -1;
  bool operator==(const EdgeId&) const = default;
};

/// The reference point's state.
struct MotionState {
  Eigen::Vector2d position{0.0, 0.0};
  MotionMode mode = MotionMode::kFree;
  EdgeId edge;                          ///< valid when mode == kSliding
  int ray = -1;                         ///< valid when mode == kOnRay
  Eigen::Vector2d direction{0.0, 0.0};  ///< unit direction of the current motion (sliding/ray), else zero
};

/// Why AdvanceToEvent returned.
enum class MotionEvent : std::uint8_t {
  kNone,          ///< the time ran out
  kContact,       ///< hit a C-obstacle edge or vertex, reached an edge's end, or changed contact
  kRay,           ///< engaged, switched or left an active ray
  kStopped,       ///< the motion stopped (sticking, a concave vertex, a zero projection on a ray)
  kReachedGoal,   ///< the position entered the closed goal
  kLeftBounds,    ///< the position would leave the bounds rectangle (failure); the position is on the border
  kOpenRayEnd,    ///< complied to an open end of an active ray (failure, see MotionWorld::active_ray_open_ends)
  kTooManyEvents  ///< Advance gave up after its event budget (a Zeno-like sequence); treat as failure
};

/// Result of moving for some time.
struct StepResult {
  MotionEvent event = MotionEvent::kNone;
  double time = 0.0;  ///< time actually advanced (s)
};

/// The motion model over an immutable world.
class MotionModel {
 public:
  /// Normalises polygon orientation and precomputes edges. Not real-time safe.
  /// @throws std::invalid_argument if a polygon has fewer than 3 vertices, the bounds are empty, a ray is
  ///         degenerate or φ is outside [0, π/2).
  explicit MotionModel(MotionWorld world);

  const MotionWorld& world() const { return world_; }
  double length_tolerance() const { return tol_; }

  /// Coulomb sticking, inclusive: v (pushing into an edge with outward normal n) sticks iff the angle between v
  /// and −n is at most φ (+ kStickAngleTolerance). False if v does not push (v·n ≥ 0).
  static bool Sticks(const Eigen::Vector2d& v, const Eigen::Vector2d& outward_normal, double friction_cone);

  /// docs/semantics.md: an edge is a sticking edge for θ if some velocity in the cone [θ−ε_v, θ+ε_v] sticks on it.
  /// Same tolerance as Sticks (a tie counts as sticking).
  static bool IsStickingEdge(const Eigen::Vector2d& outward_normal, double theta, double velocity_cone,
                             double friction_cone);

  /// Outward unit normal of an edge of the normalised obstacle polygons.
  Eigen::Vector2d OutwardNormal(EdgeId e) const;
  /// Endpoints of an edge of the normalised obstacle polygons.
  const Eigen::Vector2d& EdgeStart(EdgeId e) const;
  const Eigen::Vector2d& EdgeEnd(EdgeId e) const;

  /// Decides what the reference point does at `state.position` under actual velocity v (contact rules, vertex
  /// rules, ray engagement; no time passes). `arrived_ray` is the ray just reached (−1 if none). Returns the new
  /// state (mode kStopped if v makes no progress). Real-time safe only in the sense of no allocation: it is O(n).
  MotionState ResolveAt(const MotionState& state, const Eigen::Vector2d& v, int arrived_ray = -1) const;

  /// Moves under actual velocity v (any positive speed; m/s) for at most `max_time` seconds, stopping at the first
  /// event. Re-resolves the contact state for v first. Does not allocate.
  StepResult AdvanceToEvent(MotionState& state, const Eigen::Vector2d& v, double max_time) const;

  /// Moves under actual velocity v for `dt` seconds through any number of events (at most `max_events`), returning
  /// early on kStopped, kReachedGoal (only when entering the goal from outside), kLeftBounds, kOpenRayEnd or
  /// kTooManyEvents.
  StepResult Advance(MotionState& state, const Eigen::Vector2d& v, double dt, int max_events = 10000) const;

  /// True if p is in the closed goal (within the length tolerance).
  bool InGoal(const Eigen::Vector2d& p) const;
  /// True if p is in the closed bounds rectangle (within the length tolerance).
  bool InBounds(const Eigen::Vector2d& p) const;
  /// True if p is in the interior of some C-obstacle (farther than the tolerance from its boundary).
  bool InObstacleInterior(const Eigen::Vector2d& p) const;

 private:
  struct Incident {
    EdgeId edge;
    int at = 0;  // 0: interior of the edge, 1: at its start, 2: at its end
  };
  void CollectIncident(const Eigen::Vector2d& p, std::vector<Incident>& out) const;
  bool PointsIntoObstacle(const Eigen::Vector2d& p, const Eigen::Vector2d& d, const std::vector<Incident>& inc,
                          int skip_obstacle) const;
  bool StrictlyIntoObstacle(const Eigen::Vector2d& p, const Eigen::Vector2d& d, const std::vector<Incident>& inc,
                            int skip_obstacle) const;
  MotionState ContactRules(const Eigen::Vector2d& p, const Eigen::Vector2d& v) const;
  double RayRemaining(int ray, const Eigen::Vector2d& p, const Eigen::Vector2d& dir) const;
  Eigen::Vector2d SnapOntoEdge(EdgeId e, const Eigen::Vector2d& q) const;
  StepResult LandBesideRayEnd(MotionState& state, MotionState ns, const Eigen::Vector2d& v, const Eigen::Vector2d& q,
                              const Eigen::Vector2d& m, const Eigen::Vector2d& other_end, double time) const;

  MotionWorld world_;
  double tol_ = 1e-12;
};

/// The direction chosen by an adversary: an offset from θ in [−ε_v, ε_v] and how long to keep it.
struct AdversaryChoice {
  double offset = 0.0;                                    ///< radians, clamped to the cone by Simulate
  double hold = std::numeric_limits<double>::infinity();  ///< seconds (at unit speed = metres); ∞: until an event
};

/// Picks the actual velocity direction over time. Called at the start, after every event and when a hold expires.
class Adversary {
 public:
  virtual ~Adversary() = default;
  virtual AdversaryChoice Choose(const MotionModel& model, const MotionState& state, double theta,
                                 double velocity_cone) = 0;
};

/// Always the same offset (e.g. −ε_v, 0, +ε_v: the extreme directions).
class FixedAdversary : public Adversary {
 public:
  explicit FixedAdversary(double offset) : offset_(offset) {}
  AdversaryChoice Choose(const MotionModel&, const MotionState&, double, double) override { return {offset_}; }

 private:
  double offset_;
};

/// Random switching, seeded: after every event and at exponentially distributed times (mean `mean_hold` s), a new
/// offset: an extreme of the cone with probability 1/2, otherwise uniform in the cone.
class RandomAdversary : public Adversary {
 public:
  RandomAdversary(std::uint64_t seed, double mean_hold)
      : state_(seed ? seed : 0x9e3779b97f4a7c15ULL), mean_hold_(mean_hold) {}
  AdversaryChoice Choose(const MotionModel& model, const MotionState& state, double theta,
                         double velocity_cone) override;

 private:
  double Uniform();
  std::uint64_t state_;
  double mean_hold_;
};

/// Greedy: at every event, if the current contact admits a sticking direction it takes it; otherwise it rolls out
/// each candidate offset (extremes, centre, quarter points, the direction closest to sticking on a nearby edge)
/// as a fixed direction from the current state and commits to one whose rollout fails, else to the one with the
/// longest rollout. Deterministic.
class GreedyAdversary : public Adversary {
 public:
  explicit GreedyAdversary(int rollout_events = 2000) : rollout_events_(rollout_events) {}
  AdversaryChoice Choose(const MotionModel& model, const MotionState& state, double theta,
                         double velocity_cone) override;

 private:
  int rollout_events_;
};

/// How a whole trajectory ended.
enum class Outcome : std::uint8_t {
  kReachedGoal,
  kStopped,
  kLeftBounds,
  kNoProgress,
  kStartInObstacle,
  kOpenRayEnd,  ///< complied past an active ray's open end (out of the bounds along the VC line, or to the camera)
};

const char* OutcomeName(Outcome o);

struct SimulationOptions {
  int max_events = 20000;
  double max_time = std::numeric_limits<double>::infinity();  ///< also failure (kNoProgress) when exceeded
  bool record_path = false;
};

struct SimulationResult {
  Outcome outcome = Outcome::kNoProgress;
  MotionState final_state;
  double time = 0.0;
  int events = 0;
  std::vector<Eigen::Vector2d> path;  ///< positions at events (if record_path)
};

/// Runs one motion step with commanded direction θ (radians) and control cone half-angle ε_v (radians) from
/// `start`, the adversary choosing the actual unit velocity, until the goal is reached (success) or the motion
/// stops, leaves the bounds or makes no progress within the budget (failures). Not real-time safe.
SimulationResult Simulate(const MotionModel& model, const Eigen::Vector2d& start, double theta, double velocity_cone,
                          Adversary& adversary, const SimulationOptions& options = {});
/// Same, from a given state (used by the greedy adversary's rollouts).
SimulationResult Simulate(const MotionModel& model, const MotionState& start, double theta, double velocity_cone,
                          Adversary& adversary, const SimulationOptions& options = {});

/// Runs the standard battery of adversaries (both extremes, the centre, three seeded random switchers and the greedy
/// one) and returns the first failure, or a success if all succeed. `seed` seeds the random switchers.
SimulationResult SimulateAdversarially(const MotionModel& model, const Eigen::Vector2d& start, double theta,
                                       double velocity_cone, std::uint64_t seed = 1, bool greedy = true);

}  // namespace visco
