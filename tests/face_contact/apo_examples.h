#pragma once
// The three worked examples of Suehiro & Ikeuchi §5, built from exact geometry: ground-truth motion parameters, and
// observations = truth with the human's unobserved adjustment left out, plus seeded noise.
//
// Geometry (metres): a work table whose top is z = 0; "castles" are U-shaped prisms with a notch on top; sticks and
// cubes are boxes or U-channels. Every contact of the ground truth is an exact face contact.

#include <Eigen/Dense>
#include <numbers>
#include <random>
#include <string>
#include <vector>

#include "face_contact/assembly_plan.h"
#include "face_contact/face_contact.h"
#include "face_contact/polyhedron.h"

namespace visco::face_contact::testing {

inline Eigen::Matrix4d Pose(double x, double y, double z, double rz_deg = 0, double ry_deg = 0) {
  Vector6d q;
  q << x, y, z, 0, ry_deg * std::numbers::pi / 180, rz_deg * std::numbers::pi / 180;
  return DeltaTransform(q);
}

inline Eigen::Matrix4d WorldShift(double dx, double dy, double dz) {
  Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
  m.block<3, 1>(0, 3) = Eigen::Vector3d(dx, dy, dz);
  return m;
}

/// Noise on a pose: T·ΔT(q), q uniform in ±translation (m) and ±rotation (rad), from a seeded generator.
class Noise {
 public:
  Noise(unsigned seed, double translation, double rotation)
      : rng_(seed), translation_(translation), rotation_(rotation) {}
  Eigen::Matrix4d operator()(const Eigen::Matrix4d& pose) {
    Vector6d q;
    for (int i = 0; i < 6; ++i) q[i] = (i < 3 ? translation_ : rotation_) * (2 * Uniform() - 1);
    return pose * DeltaTransform(q);
  }
  double Uniform() { return std::generate_canonical<double, 53>(rng_); }

 private:
  std::mt19937_64 rng_;
  double translation_;
  double rotation_;
};

/// A U-shaped castle: width w (x), height h, notch width n and depth d on top, length l (y).
inline Polyhedron Castle(double w, double h, double n, double d, double l) {
  return MakePrism(
      {{-w / 2, 0}, {w / 2, 0}, {w / 2, h}, {n / 2, h}, {n / 2, h - d}, {-n / 2, h - d}, {-n / 2, h}, {-w / 2, h}}, l);
}

/// An inverted U (channel of width n and height c on the bottom), width w, height h, length l.
inline Polyhedron Channel(double w, double h, double n, double c, double l) {
  return MakePrism({{-w / 2, 0}, {-n / 2, 0}, {-n / 2, c}, {n / 2, c}, {n / 2, 0}, {w / 2, 0}, {w / 2, h}, {-w / 2, h}},
                   l);
}

struct Example {
  std::string name;
  ApoObservation observation;
  std::vector<Eigen::Matrix4d> truth;  ///< per operation (identity for removals), the real final motion parameters.
  /// Per operation: the trials the paper's iterative mode makes (1-based operation numbers).
  std::vector<std::vector<std::vector<int>>> expected_trials;
};

inline int AddObject(ApoObservation& obs, const std::string& id, Polyhedron model, bool stable = false,
                     const Eigen::Matrix4d& pose = Eigen::Matrix4d::Identity()) {
  obs.objects.push_back({id, std::move(model), stable, pose});
  return static_cast<int>(obs.objects.size()) - 1;
}

inline void Place(Example& ex, int object, const Eigen::Matrix4d& truth, const Eigen::Matrix4d& observed,
                  std::vector<int> carries = {}) {
  ApoOperation op;
  op.object = object;
  op.observed = observed;
  op.carries = std::move(carries);
  ex.observation.operations.push_back(op);
  ex.truth.push_back(truth);
}

inline void Remove(Example& ex, int object) {
  ApoOperation op;
  op.kind = ApoOperation::Kind::kRemove;
  op.object = object;
  ex.observation.operations.push_back(op);
  ex.truth.push_back(Eigen::Matrix4d::Identity());
}

constexpr double kHumanError = 0.001;  // the unobserved adjustment of §5 (1 mm)

/// §5.1: castle1 on the table, castle2 upside down on castle1 (their notches form a tunnel), a stick through the
/// tunnel. The human's step-2 placement left castle2 1 mm off in x; at step 3 the human pushed it back, unobserved.
inline Example CastlesAndStick(unsigned seed, double noise_t = 2e-4, double noise_r = 1.5e-3) {
  Example ex;
  ex.name = "5.1 castles and stick";
  Noise noise(seed, noise_t, noise_r);
  ApoObservation& obs = ex.observation;
  AddObject(obs, "table", MakeBox({1, 1, 0.05}), true, Pose(0, 0, -0.05));
  const int c1 = AddObject(obs, "castle1", Castle(0.08, 0.04, 0.02, 0.02, 0.06));
  const int c2 = AddObject(obs, "castle2", Castle(0.08, 0.04, 0.02, 0.02, 0.06));
  const int stick = AddObject(obs, "stick", MakeBox({0.02, 0.2, 0.04}));
  const Eigen::Matrix4d t1 = Pose(0, 0, 0, 0);
  const Eigen::Matrix4d t2 = Pose(0, 0, 0.08, 0, 180);
  const Eigen::Matrix4d t3 = Pose(0, 0, 0.02);
  Place(ex, c1, t1, noise(t1));
  Place(ex, c2, t2, noise(WorldShift(kHumanError, 0, 0) * t2));
  Place(ex, stick, t3, noise(t3));
  ex.expected_trials = {{{1}}, {{2}}, {{3}, {3, 2}}};
  return ex;
}

// Castles of §5.2 and §5.3: notch along the world x axis (prism rotated 90° about z).
inline Polyhedron PillarCastle() { return Castle(0.04, 0.05, 0.02, 0.01, 0.04); }

/// §5.2: castle1 and castle2 on the table; a cube (a U-channel) on castle1; a stick into the cube's channel (stick
/// and cube are sub-assembled); cube and stick together onto both castles, the stick in both notches. Castle2 was
/// observed 1 mm off in y at step 2.
inline Example SubAssembly(unsigned seed, double noise_t = 2e-4, double noise_r = 1.5e-3) {
  Example ex;
  ex.name = "5.2 sub-assembly";
  Noise noise(seed, noise_t, noise_r);
  ApoObservation& obs = ex.observation;
  AddObject(obs, "table", MakeBox({1, 1, 0.05}), true, Pose(0, 0, -0.05));
  const int c1 = AddObject(obs, "castle1", PillarCastle());
  const int c2 = AddObject(obs, "castle2", PillarCastle());
  const int cube = AddObject(obs, "cube", Channel(0.04, 0.04, 0.02, 0.02, 0.04));
  const int stick = AddObject(obs, "stick", MakeBox({0.02, 0.3, 0.02}));
  const Eigen::Matrix4d t1 = Pose(-0.1, 0, 0, 90);
  const Eigen::Matrix4d t2 = Pose(0.1, 0, 0, 90);
  const Eigen::Matrix4d t3 = Pose(-0.1, 0, 0.05);
  const Eigen::Matrix4d t4 = Pose(-0.1, 0, 0.05);
  const Eigen::Matrix4d t5 = Pose(0, 0, 0.04, 90);
  Place(ex, c1, t1, noise(t1));
  Place(ex, c2, t2, noise(WorldShift(0, kHumanError, 0) * t2));
  Place(ex, cube, t3, noise(t3));
  Place(ex, stick, t4, noise(t4));
  Place(ex, cube, t5, noise(t5), {stick});
  ex.expected_trials = {{{1}}, {{2}}, {{3}}, {{4}}, {{5}, {5, 4}, {5, 4, 3}, {5, 4, 3, 2}}};
  return ex;
}

/// §5.3: castle1 on the table; a cube on the table as a fixture; castle2 pushed against the cube; the cube removed;
/// a stick onto both castles. The cube and castle2 were observed 1 mm off in y together.
inline Example DisappearedRelation(unsigned seed, double noise_t = 2e-4, double noise_r = 1.5e-3) {
  Example ex;
  ex.name = "5.3 disappeared relation";
  Noise noise(seed, noise_t, noise_r);
  ApoObservation& obs = ex.observation;
  AddObject(obs, "table", MakeBox({1, 1, 0.05}), true, Pose(0, 0, -0.05));
  const int c1 = AddObject(obs, "castle1", PillarCastle());
  const int cube = AddObject(obs, "cube", MakeBox({0.04, 0.04, 0.04}));
  const int c2 = AddObject(obs, "castle2", PillarCastle());
  const int stick = AddObject(obs, "stick", MakeBox({0.02, 0.3, 0.02}));
  const Eigen::Matrix4d t1 = Pose(-0.1, 0, 0, 90);
  const Eigen::Matrix4d t2 = Pose(0.1, -0.04, 0);
  const Eigen::Matrix4d t3 = Pose(0.1, 0, 0, 90);
  const Eigen::Matrix4d t5 = Pose(0, 0, 0.04, 90);
  Place(ex, c1, t1, noise(t1));
  Place(ex, cube, t2, noise(WorldShift(0, kHumanError, 0) * t2));
  Place(ex, c2, t3, noise(WorldShift(0, kHumanError, 0) * t3));
  Remove(ex, cube);
  Place(ex, stick, t5, noise(t5));
  ex.expected_trials = {{{1}}, {{2}}, {{3}}, {}, {{5}, {5, 3}, {5, 3, 2}}};
  return ex;
}

}  // namespace visco::face_contact::testing
