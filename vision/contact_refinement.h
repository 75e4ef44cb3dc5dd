#pragma once
// Object poses made mutually consistent with their face contacts (Suehiro & Ikeuchi 1991): the poses measured from
// the tags are moved, as little as possible, until the faces that touch (each object's base on the table, obstacles
// side by side, the robot against an obstacle) are exactly flush. The work is face_contact's MakeFlush
// (face_contact/flush_poses.h); this is the glue from vision's object models (vertical prisms standing on the table,
// world z = 0) to face_contact's polyhedra. Plain Eigen types only.
//
// Dependency: vision -> face_contact (which depends on neither vision nor the planner). face_contact's headers are
// C++20 and vision is compiled as C++17 for ViSP 3.5's headers, so contact_refinement.cc alone is compiled as C++20 (it
// includes no ViSP or OpenCV header).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "vision/object_model.h"

namespace visco::vision {

/// When two faces count as touching: per face pair, within what the two poses' own uncertainty explains (the gaps
/// and the normals' angle propagated through the pair's geometry from the covariances, thresholded so that a true
/// contact is missed with probability at most `false_miss_probability`: face_contact's ContactThresholds), never below
/// the floors `min_distance_m` and `min_angle_deg` (model tolerance). docs/vision.md, "Face contacts".
/// 6 x 6 pose covariance.
using PoseCovariance = Eigen::Matrix<double, 6, 6>;

struct ContactOptions {
  bool enabled = true;
  double false_miss_probability = 1e-3;  ///< as the hysteresis' false alarm (alpha = 1e-3; docs/vision.md)
  double min_distance_m = 0.0005;
  double min_angle_deg = 0.5;
  double table_thickness_m = 0.05;  ///< the table, a stable box whose top face is the plane z = 0
  /// Uncertainty of the table plane relative to the measured objects, as a rigid motion of the table about the world
  /// origin (p' = Exp(w) p + v; covariance of [w, v], radians and metres). Only the contact thresholds use it (the
  /// table's contacts are then missed no more often than promised when the table is not where the world says); the
  /// poses are still made flush with z = 0. FeatureEstimator adds the extrinsics' uncertainty
  /// (NoiseModel::extrinsics_covariance) to it. Zero: the table is exact.
  PoseCovariance table_covariance = PoseCovariance::Zero();
};

/// The cross-product matrix: Skew(a) b = a x b.
inline Eigen::Matrix3d Skew(const Eigen::Vector3d& a) {
  Eigen::Matrix3d m;
  m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return m;
}

/// The pose perturbation every visco pose covariance is expressed in: rotation vector w on the left, then translation
/// (R' = Exp(w) R, t' = t + v; d = [w, v]). In the frame `m` is expressed in (camera frame for cMo, world for wMo).
Eigen::Isometry3d PerturbPose(const Eigen::Isometry3d& m, const Eigen::Matrix<double, 6, 1>& d);

/// One object as measured.
struct ContactObject {
  const ObjectModel* model = nullptr;
  Eigen::Isometry3d wMo = Eigen::Isometry3d::Identity();
  double position_stddev = 0;     ///< metres, 1 sigma
  double orientation_stddev = 0;  ///< radians, 1 sigma
  /// Covariance of wMo in the world frame: rotation vector perturbation on the left (R' = Exp(w) R, radians), then
  /// translation of the origin (t' = t + v, metres). Zero: unknown (then the contact thresholds are derived from
  /// the stddevs above as an isotropic covariance, the poses are MakeFlush's and no covariance is propagated, see
  /// RefineContacts).
  PoseCovariance covariance = PoseCovariance::Zero();
};

struct ContactRefinement {
  bool ok = false;                     ///< every contact found holds; `wMo` are the flush poses
  std::vector<Eigen::Isometry3d> wMo;  ///< same order as the input (the measured ones if !ok)
  std::vector<bool> in_contact;        ///< the object takes part in at least one face contact
  int contacts = 0;                    ///< face contacts found (table contacts included)
  double observed_gap_m = 0;           ///< largest |gap| of the contacts as measured
  double max_residue_m = 0;            ///< largest |gap| after the correction
  /// Per object, the covariance of `wMo` (ContactObject::covariance's convention): the measured one propagated
  /// through the contact constraints when `covariance_propagated`, else the input's.
  std::vector<PoseCovariance> covariance;
  /// The joint covariance of all objects' wMo (6 rows per object, input order, the same convention): the projection
  /// moves the objects in contact together, so their refined poses are correlated (off-diagonal blocks). Without
  /// propagation, block-diagonal with the inputs' covariances.
  Eigen::MatrixXd joint_covariance;
  bool covariance_propagated = false;
  std::string message;
};

/// The vertical prism of `model` as a polyhedron (object frame: polygon in x y, z from 0 to height), as face_contact's
/// vertices and faces: bottom, top, then one side per polygon edge. Exposed for tests.
struct PrismMesh {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::vector<int>> faces;
};
PrismMesh ObjectPrism(const ObjectModel& model);

/// Makes the objects flush with the table (z = 0) and with each other. Not real-time safe (allocates).
///
/// face_contact's MakeFlush finds the touching faces (thresholds derived from each pair's covariance, ContactOptions).
/// When every object in a contact has a covariance, the flush poses are then the measured ones projected onto the
/// contact constraints in the metric of their covariance (the most likely poses that satisfy the contacts: minimise d^T
/// Sigma^-1 d subject to c(d) = 0, Gauss-Newton from the measurement), and their covariance is propagated to first
/// order: Sigma' = Sigma - Sigma J^T (J Sigma J^T)^+ J Sigma, J the Jacobian of the contact equations c (per contact:
/// the two faces' normals opposite, 2 equations, and the face planes coincident, 1 equation) with respect to the
/// stacked pose perturbations, by central differences at the flush poses (docs/vision.md). Otherwise the poses are
/// MakeFlush's own (the smallest change in its characteristic-length metric) and the covariances are left as given.
ContactRefinement RefineContacts(const std::vector<ContactObject>& objects, const ContactOptions& options = {});

}  // namespace visco::vision
