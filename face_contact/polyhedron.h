#pragma once
// Polyhedral object models and face contacts between them (Suehiro & Ikeuchi §1–2): faces with plane equations in
// the object frame, and the contact region F_c of two faces that touch (the projection of one face onto the other),
// whose vertices give the face contact equations.
//
// Units: metres. A pose wMo maps object coordinates to world coordinates (4×4 homogeneous, rigid).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

namespace visco::face_contact {

/// A closed polyhedron in its object frame. Faces list vertex indices counter-clockwise seen from outside (so that
/// the right-hand normal points out of the solid); faces may be non-convex simple polygons.
struct Polyhedron {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<std::vector<int>> faces;
};

/// A box of the given size (x, y, z), frame at the centre of its bottom face: x ∈ ±sx/2, y ∈ ±sy/2, z ∈ [0, sz].
/// Faces: 0 bottom (−z), 1 top (+z), then the sides.
Polyhedron MakeBox(const Eigen::Vector3d& size);

/// A prism: the simple polygon `profile` (points (x, z), counter-clockwise with x to the right and z up) extruded
/// along y over [−length/2, length/2]. Faces: 0 the front (y = −length/2), 1 the back, then one side per profile
/// edge i → i+1 (face 2 + i).
Polyhedron MakePrism(const std::vector<Eigen::Vector2d>& profile, double length);

/// Why the model is unusable, or an empty string: index out of range, fewer than three distinct vertices, zero area,
/// a vertex farther than `planarity_tolerance` (metres) from its face's plane, or faces oriented inwards (negative
/// volume). The message names the face and vertex.
std::string CheckPolyhedron(const Polyhedron& model, double planarity_tolerance);

/// The plane (n_x, n_y, n_z, −d) of a face in the object frame, |n| = 1, n pointing out of the solid (Newell).
Eigen::Vector4d FacePlane(const Polyhedron& model, int face);

/// What counts as touching (footnote 1 of the paper: a threshold on the small observed gap). Without a pose
/// covariance the gap and the angle are compared with the fixed `distance` and `angle_deg`. With one
/// (FindFaceContacts' `covariance`) they are derived per face pair from the two poses' uncertainty: the gap of every
/// contact vertex and the deviation of the two normals from opposite are propagated through the face pair's geometry,
/// and the pair touches when each is within what the noise explains at the false-miss probability
/// `false_miss_probability` (a true contact observed with that noise is missed at most that often), never below the
/// floors `min_distance` and `min_angle_deg` (model tolerance). docs/apo.md, "Thresholds from the pose noise".
struct ContactThresholds {
  double distance = 0.003;   ///< metres: every contact vertex within this of the other face's plane.
  double angle_deg = 3.0;    ///< the two outward normals opposite within this angle.
  double min_width = 0.002;  ///< metres: the contact region is at least this wide (thinner overlaps are edges).
  double false_miss_probability = 1e-3;  ///< derived thresholds: half for the gaps, half for the angle.
  double min_distance = 0.0005;          ///< metres: floor of the derived gap threshold.
  double min_angle_deg = 0.5;            ///< floor of the derived angle threshold.
};

/// Covariance of an observed pose: of the perturbation q = (x, y, z, α, β, γ) in wMo·ΔT(q) (face_contact/face_contact.h
/// DeltaTransform: object frame, metres and radians).
using PoseCovariance = Eigen::Matrix<double, 6, 6>;
/// Covariance of two objects' perturbations (q_a, q_b), with their cross terms (objects whose poses share an
/// observation, as a carried object and its carrier).
using PairCovariance = Eigen::Matrix<double, 12, 12>;

/// Inverse of the standard normal distribution function (bisection on erfc; p in (0, 1)).
double NormalQuantile(double p);

/// A face of object A touching a face of object B.
struct FacePatch {
  int face = -1;                        ///< A's face (its plane gives n).
  int against_face = -1;                ///< B's face.
  std::vector<Eigen::Vector3d> points;  ///< vertices of the contact region F_c in B's frame (convex hull, ≥ 3).
  double max_gap = 0;                   ///< max |distance| of the points to A's face plane at the given poses.
  double distance_threshold = 0;        ///< the gap threshold applied (largest over the points when derived).
  double width = 0;                     ///< the region's minimum width, metres.
};

/// The contact region of face `face_a` of A against face `face_b` of B at the given poses: A's face projected onto
/// B's face plane and intersected with B's face; its convex hull, in B's frame. Empty when the faces do not
/// overlap or the overlap is thinner than `min_width`. Orientation and distance are not checked here.
std::optional<FacePatch> FaceOverlap(const Polyhedron& a, const Eigen::Matrix4d& wMa, int face_a, const Polyhedron& b,
                                     const Eigen::Matrix4d& wMb, int face_b, double min_width);

/// Every face of A that touches a face of B at the given poses (normals opposite, region wide enough, every region
/// vertex close to A's face plane).
/// With `covariance` (not null) the distance and angle thresholds are derived from it (ContactThresholds).
std::vector<FacePatch> FindFaceContacts(const Polyhedron& a, const Eigen::Matrix4d& wMa, const Polyhedron& b,
                                        const Eigen::Matrix4d& wMb, const ContactThresholds& thresholds,
                                        const PairCovariance* covariance = nullptr);

}  // namespace visco::face_contact
