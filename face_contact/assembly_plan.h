#pragma once
// Assembly plan from observation (Suehiro & Ikeuchi 1991, §3–4): an observed sequence of assembly operations,
// the face contact relation graph they build, operation dependency lists (ODLs), and the correction of the
// operations' motion parameters so that every face contact holds exactly; then the robot's assembly plan.
//
// Motion parameters: T_0 for each stable object (its fixed pose, never corrected) and T_i for operation i (1-based
// in text, 0-based in the vectors here): the goal configuration of the operation's manipulated object in the world.
// Units: metres, radians; poses map object coordinates to world coordinates (wMo).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "face_contact/face_contact.h"
#include "face_contact/polyhedron.h"

namespace visco::face_contact {

/// An object of the assembly. Stable objects (the work table) are fixed at `pose` from the start.
struct ApoObject {
  std::string id;
  Polyhedron model;
  bool stable = false;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();  ///< stable objects only.
};

/// A face contact named by the observation instead of being found from the poses.
struct GivenContact {
  int object = -1;  ///< the face owner: moved by the operation (manipulated or carried).
  int face = -1;
  int against = -1;                     ///< the environment object (its points lie on `face`).
  int against_face = -1;                ///< used to compute the contact region when `points` is empty.
  std::vector<Eigen::Vector3d> points;  ///< optional contact vertices in `against`'s frame (≥ 3, not collinear).
};

/// One observed operation.
struct ApoOperation {
  enum class Kind { kPlace, kRemove };
  Kind kind = Kind::kPlace;
  int object = -1;                                         ///< the manipulated object.
  Eigen::Matrix4d observed = Eigen::Matrix4d::Identity();  ///< place: observed goal configuration (wMo).
  std::vector<int> carries;                                ///< sub-assembled objects moving with `object`.
  std::optional<std::vector<GivenContact>> contacts;       ///< place: given contacts (otherwise found).
  /// place: covariance of the observed pose (PoseCovariance: observed·ΔT(q), object frame); otherwise
  /// ApoOptions::pose_noise. With one, contacts are found with thresholds derived from it (ContactThresholds).
  std::optional<PoseCovariance> covariance;
};

struct ApoObservation {
  std::vector<ApoObject> objects;
  std::vector<ApoOperation> operations;
};

/// §4.2: correct after each operation, trying the k most recent candidate operations (k = 1, 2, …), or correct
/// the whole observed sequence at once.
enum class ApoMode { kIterative, kAllAtOnce };

struct ApoOptions {
  ApoMode mode = ApoMode::kIterative;
  ContactThresholds contact;  ///< what counts as touching in the observed poses.
  /// Covariance of every observed operation pose without its own (ApoOperation::covariance); none: the fixed
  /// thresholds of `contact`. Stable objects are exact.
  std::optional<PoseCovariance> pose_noise;
  double residue_threshold = 1e-9;     ///< metres: relations with a larger residue are selected for correction.
  SolverOptions solver;                ///< its residue_tolerance must be below residue_threshold.
  std::string source = "observation";  ///< the file name, for error messages.
};

/// An arc of the face contact relation graph: the face owner's faces against the vertex owner's faces, formed by one
/// operation, kept after it disappears (§3.2.2), with the ODLs current when it formed.
struct Relation {
  int formed_by = -1;      ///< operation index.
  int face_object = -1;    ///< manipulated side (n).
  int vertex_object = -1;  ///< environment side (v).
  Odl chain;               ///< D_face⁻¹·D_vertex at formation.
  std::vector<FacePatch> patches;
  bool given = false;
  int disappeared_by = -1;       ///< operation after which the contact is gone, or −1.
  double observed_residue = 0;   ///< max |e| with the observed parameters, metres.
  double corrected_residue = 0;  ///< max |e| with the corrected parameters, metres.
};

/// One correction attempt with a set of variable operations.
struct ApoTrial {
  std::vector<int> operations;  ///< operation indices, most recent first.
  bool success = false;
  SolveReport report;
  double max_relation_residue = 0;  ///< over every relation of the graph after the attempt.
  int worst_relation = -1;
};

/// A robot action.
struct RobotAction {
  enum class Kind {
    kPlace,       ///< move `object` (with `carries`) to `pose`.
    kRemove,      ///< take `object` (with `carries`) out of the scene.
    kUndoPlace,   ///< disassembly: move `object` back to `pose` (its configuration before the operation), or away.
    kUndoRemove,  ///< disassembly: put a removed `object` back at `pose`.
  };
  Kind kind = Kind::kPlace;
  int operation = -1;
  int object = -1;
  std::vector<int> carries;
  std::optional<Eigen::Matrix4d> pose;  ///< none when an undone placement takes the object away.
  bool corrected = false;               ///< the pose is a corrected motion parameter.
};

/// What happened after one operation (iterative) or for the whole sequence (all-at-once, operation −1).
struct ApoStep {
  int operation = -1;
  std::vector<int> new_relations;
  std::vector<int> disappeared_relations;
  std::vector<int> selected;    ///< relations with a residue above the threshold.
  std::vector<int> candidates;  ///< operations connected to them in the graph, most recent first.
  std::vector<ApoTrial> trials;
  int accepted = -1;  ///< index into trials.
  std::vector<RobotAction> robot;
};

struct ApoResult {
  ApoMode mode = ApoMode::kIterative;
  int stable_count = 0;  ///< parameters 0..stable_count−1 are the stable objects' T_0.
  std::vector<Relation> relations;
  std::vector<ApoStep> steps;
  std::vector<Eigen::Matrix4d> observed;   ///< per parameter (stable objects first, then operations).
  std::vector<Eigen::Matrix4d> corrected;  ///< per parameter.
  std::vector<bool> changed;               ///< per operation: the correction is larger than the threshold.
  std::vector<RobotAction> plan;           ///< the whole assembly from scratch with the corrected parameters.
};

/// Parameter index of operation i.
inline int OperationParam(const ApoResult& result, int operation) { return result.stable_count + operation; }

/// Validate the observation, build the relation graph and correct the motion parameters.
/// @throws visco::InputError (source, object, what) for unknown ids, stable objects moved, relations of an object
/// with itself, invalid or non-planar models, degenerate given contacts, and contacts that cannot all hold even
/// when every related operation is corrected. Not real-time safe.
ApoResult PlanFromObservation(const ApoObservation& observation, const ApoOptions& options);

/// The configuration of every object present after the last operation (nullopt when removed), per object.
std::vector<std::optional<Eigen::Matrix4d>> FinalPoses(const ApoObservation& observation, const ApoResult& result,
                                                       bool corrected);

}  // namespace visco::face_contact
