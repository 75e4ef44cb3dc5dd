#pragma once
// The strategy executor: a state machine that runs a Task step by step, one Update per control period.
//
//   Idle --driver ready--> step k: Free | VisualGuarded | VisualCompliant --terminated--> step k+1 ... --> Done
//   any --estop / driver silent or faulted / limit / step time-out / vision lost too long--> Stopped (latched)
//   a step whose visual input is stale or missing is *held*: zero command within the same period, a fault
//   raised, the step resumed (fault cleared) when fresh input returns, Stopped after `max_hold_s`.
//
// Per step: the commanded velocity is speed * (cos θ, sin θ) (Free); when the reference point reaches an active
// CVC ray (its event goes on-line or changes side), the step servos along that ray (VisualCompliant, servo_law.h)
// until contact; a step terminates on the goal kernel (goal), on the named ray's crossing (vc, "visual guarded"),
// or when the robot stops in contact (contact). Every stop and hold carries its reason as a FaultEvent.
// Update is real-time safe: no allocation, no locks, no exceptions, no I/O.

#include <cstdint>
#include <vector>

#include "control/safety.h"
#include "control/servo_law.h"
#include "control/task.h"
#include "control/types.h"

namespace visco::control {

/// Telemetry modes (values equal controller_telemetry_t::MODE_*).
enum class Mode : std::int8_t {
  kIdle = 0,
  kFree = 1,
  kVisualGuarded = 2,
  kVisualCompliant = 3,
  kDone = 4,
  kStopped = 5
};
const char* ToString(Mode mode);

/// Fault codes (values equal fault_t::CODE_*).
enum class FaultCode : std::int32_t {
  kNone = 0,
  kEstop = 1,
  kVisionLost = 2,
  kVisionStale = 3,
  kPeerTimeout = 4,
  kCanError = 5,
  kBadMessage = 6,
  kLimit = 7,
  kStepTimeout = 8,
  kStrategyFailed = 9,
  kOverrun = 10,
  kRobotFault = 12,
};

/// A fault, stop or clearance announcement (fault_t) produced by the loop.
struct FaultEvent {
  std::int64_t utime = 0;
  FaultCode code = FaultCode::kNone;
  std::int8_t severity = 0;  // fault_t::SEVERITY_*
  bool robot_stopped = false;
  bool cleared = false;
  char message[160] = {};
};

struct ExecutorConfig {
  double period_s = 0.002;             // s, control period (used for the acceleration limit)
  double default_speed = 0.05;         // m/s, when the strategy gives none
  double default_step_timeout_s = 60;  // s, for steps without their own time-out
  double max_vision_age_s = 0.1;       // s, visual events / estimates older than this are stale
  double max_hold_s = 2.0;             // s, a hold longer than this stops the robot
  double heartbeat_timeout_s = 0.1;    // s, driver silent (no heartbeat, no status) longer than this: stop
  double startup_timeout_s = 5.0;      // s, the driver must report ready within this after Start
  double contact_speed = 0.002;        // m/s, below this speed in contact the motion has stopped
  double contact_dwell_s = 0.02;       // s, ... for at least this long (contact termination)
  double contact_min_step_s = 0.1;     // s, a contact step cannot end before it had time to start moving
  // A goal- or ray-terminated step whose robot stays in contact within stuck_distance (m) for stuck_s (s), farther
  // than ε_p from the goal, is stuck for good (sticking is final under a constant direction): it fails then, with
  // CODE_STRATEGY_FAILED, instead of at its time-out. 0 disables.
  double stuck_s = 2.0;
  double stuck_distance = 0.001;
  bool goal_from_odometry = false;  // recognise the goal from the driver's odometry instead of vision
  /// m, > 0: near a VC line not yet reached, the speed is cut so that the motion goes past the line by at most this
  /// before the event is seen (one frame interval plus the frame's age late): the planner's strip half-width
  /// (planning::kVcStripHalfWidth). 0: full speed up to the line.
  double approach_tolerance_m = 0.01;
  ServoConfig servo;
  SafetyLimits limits;
};

/// Everything the executor reads in one period. The loop keeps one instance and overwrites fields as new data
/// arrives (the `have_*` flags say whether any value was ever received).
struct ExecutorInput {
  std::int64_t now_ns = 0;     // monotonic
  std::int64_t now_utime = 0;  // microseconds since the epoch, for stamping
  bool have_status = false;
  RobotStatus status;
  std::int64_t heartbeat_ns = 0;     // monotonic time the driver's heartbeat was last seen alive (0: never)
  bool peer_lost = false;            // the link judges the driver's heartbeat lost
  std::int32_t link_fault_code = 0;  // FaultCode of a fault the robot link reported (0: none); latched by the loop
  char link_fault[128] = {};         // ... in words
  bool have_frame = false;
  VisualFrame frame;
  bool have_estimate = false;
  PositionEstimate estimate;
  bool estop = false;  // e-stop requested (latched by the executor)
};

inline constexpr int kMaxFaultsPerUpdate = 4;

/// What one period produces.
struct ExecutorOutput {
  RobotCommand command;
  Mode mode = Mode::kIdle;
  std::int32_t step_index = -1;  // -1 before the first step, num_steps when done
  bool holding = false;
  char stop_reason[128] = {};  // empty while running
  char step_reason[128] = {};  // why the previous step ended (empty before the second step)
  Vec2 estimate;               // metres, position used for goal recognition / bounds
  double estimate_age_s = 0.0;
  std::int32_t num_faults = 0;
  FaultEvent faults[kMaxFaultsPerUpdate];
};

class Executor {
 public:
  /// Not real-time safe: allocates per-step state. @throws InputError via ValidateTask if the task is unusable.
  Executor(const Task& task, const ExecutorConfig& config);

  /// Arms the executor at monotonic time `now_ns`: it waits for the driver, then runs step 0. Real-time safe.
  void Start(std::int64_t now_ns);
  /// Runs one period. Real-time safe.
  void Update(const ExecutorInput& in, ExecutorOutput& out);

  Mode mode() const { return mode_; }
  int step_index() const { return step_; }
  bool finished() const { return mode_ == Mode::kDone || mode_ == Mode::kStopped; }
  const char* stop_reason() const { return stop_reason_; }
  FaultCode stop_code() const { return stop_code_; }
  const Task& task() const { return task_; }
  const ExecutorConfig& config() const { return config_; }

 private:
  enum class Side : std::int8_t { kUnknown = 0, kNegative = 1, kOnLine = 2, kPositive = 3 };
  struct RayState {
    Side first_side = Side::kUnknown;
    bool reached = false;
  };

  void BeginStep(int index, std::int64_t now_ns, int reached_ray = -1);
  void Stop(FaultCode code, const char* message, ExecutorOutput& out, const ExecutorInput& in);
  void AddFault(ExecutorOutput& out, const ExecutorInput& in, FaultCode code, std::int8_t severity, bool stopped,
                bool cleared, const char* message);
  const VisualObservation* Find(const VisualFrame& frame, int ray) const;
  // Updates the per-ray side tracking with `obs`; returns true if the ray has just been reached.
  bool TrackRay(int ray, const VisualObservation& obs);
  // The speed that keeps the overshoot past the step's VC lines not yet reached within approach_tolerance_m.
  double ApproachSpeed(const ExecutorInput& in, const Step& step, Vec2 estimate) const;
  void Finish(ExecutorOutput& out, const ExecutorInput& in, Vec2 nominal, bool zero);

  Task task_;
  ExecutorConfig config_;
  SafetyFilter safety_;
  double speed_;
  Mode mode_ = Mode::kIdle;
  bool started_ = false;
  std::int64_t start_ns_ = 0;
  int step_ = -1;
  std::int64_t step_start_ns_ = 0;
  std::int64_t last_frame_seq_ = -1;   // newest frame already processed
  std::int64_t last_capture_ns_ = -1;  // its capture time
  double frame_interval_s_ = 0.0;      // between the last two frames' captures
  std::vector<RayState> rays_;         // per ray, for the current step (sized at construction)
  int engaged_ray_ = -1;
  bool contact_latched_ = false;  // contact ended the compliant motion; re-engage only after it clears
  std::int64_t contact_since_ns_ = -1;
  std::int64_t stuck_since_ns_ = -1;  // in contact near stuck_at_ since then (-1: not in contact)
  Vec2 stuck_at_{};
  bool holding_ = false;
  FaultCode hold_code_ = FaultCode::kNone;
  std::int64_t hold_since_ns_ = 0;
  char hold_reason_[128] = {};
  char stop_reason_[128] = {};
  char step_reason_[128] = {};
  FaultCode stop_code_ = FaultCode::kNone;
  bool estop_latched_ = false;
  Vec2 last_command_;
  std::int32_t seq_ = 0;
};

}  // namespace visco::control
