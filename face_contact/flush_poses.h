#pragma once
// Make observed object poses consistent with their face contacts (Suehiro & Ikeuchi 1991, §2), for vision:
// objects seen resting on the table or touching each other are moved, as little as possible, until the touching
// faces are exactly flush. Call it on the poses from the camera before the planner builds its scene.
//
//   std::vector<visco::face_contact::FlushObject> objects = {
//       {"table", visco::face_contact::MakeBox({1, 1, 0.05}), wMtable, /*stable=*/true},
//       {"block", visco::face_contact::MakeBox({0.1, 0.1, 0.05}), wMblock_seen}};
//   const visco::face_contact::FlushResult flush = visco::face_contact::MakeFlush(objects);
//   if (flush.ok) use(flush.poses[1]);   // else flush.message says why; flush.poses are the observed ones
//
// Units: metres. Poses wMo map object coordinates to world (or camera) coordinates; any one fixed frame will do.

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "face_contact/face_contact.h"
#include "face_contact/polyhedron.h"

namespace visco::face_contact {

/// An object as seen: its model (face_contact/polyhedron.h: MakeBox, MakePrism or vertices and faces), its observed
/// pose, and whether it is stable (fixed: the table; never moved).
struct FlushObject {
  std::string id;
  Polyhedron model;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  bool stable = false;
  /// Covariance of the observed pose (face_contact/polyhedron.h PoseCovariance: wMo·ΔT(q), object frame). Zero: exact
  /// or unknown. When any object of a pair has one, that pair's contact thresholds are derived from it
  /// (ContactThresholds: false_miss_probability, min_distance, min_angle_deg) instead of the fixed ones.
  PoseCovariance covariance = PoseCovariance::Zero();
};

struct FlushOptions {
  ContactThresholds contact;  ///< what counts as touching in the observed poses (3 mm, 3°, 2 mm wide, or derived).
  SolverOptions solver;       ///< characteristic length (0.1 m) and tolerances.
};

/// A pair of faces found touching.
struct FlushContact {
  int object = -1;  ///< index of the object whose face plane is used (the face side).
  int face = -1;
  int against = -1;  ///< index of the other object (its contact region's vertices are used).
  int against_face = -1;
  double observed_gap = 0;  ///< max |distance| of the contact vertices to the face plane as observed, metres.
};

struct FlushResult {
  bool ok = false;                       ///< every contact holds (|e| ≤ solver.residue_tolerance).
  std::vector<Eigen::Isometry3d> poses;  ///< corrected poses, same order as the input (observed ones if !ok).
  std::vector<FlushContact> contacts;
  SolveReport report;   ///< iterations, rank, residues, null-space certificate.
  std::string message;  ///< one sentence: what happened.
};

/// Find the touching faces among `objects` (every pair; the face side is the non-stable object, or the later one in
/// the list when both move) and correct the non-stable poses by the smallest change (weighted by the characteristic
/// length) that makes every contact exact; directions the contacts do not constrain keep their observed values.
/// @throws std::invalid_argument if a model is invalid (CheckPolyhedron) or a pose is not rigid.
/// Not real-time safe (allocates; a few milliseconds for a handful of objects).
FlushResult MakeFlush(const std::vector<FlushObject>& objects, const FlushOptions& options = {});

}  // namespace visco::face_contact
