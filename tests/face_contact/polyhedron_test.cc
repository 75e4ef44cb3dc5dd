// Polyhedral models and the contact regions of touching faces.

#include "face_contact/polyhedron.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "face_contact/face_contact.h"
#include "tests/face_contact/apo_examples.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;
using Eigen::Vector3d;

TEST(Polyhedron, BoxAndPrismAreValidWithOutwardNormals) {
  const Polyhedron box = MakeBox({0.1, 0.2, 0.3});
  EXPECT_EQ(CheckPolyhedron(box, 1e-12), "");
  EXPECT_TRUE(FacePlane(box, 0).isApprox(Eigen::Vector4d(0, 0, -1, 0)));
  EXPECT_TRUE(FacePlane(box, 1).isApprox(Eigen::Vector4d(0, 0, 1, -0.3)));
  const Polyhedron castle = testing::Castle(0.08, 0.04, 0.02, 0.02, 0.06);
  EXPECT_EQ(CheckPolyhedron(castle, 1e-12), "");
  EXPECT_EQ(castle.faces.size(), 10u);
  EXPECT_TRUE(FacePlane(castle, 0).isApprox(Eigen::Vector4d(0, -1, 0, -0.03)));  // front, non-convex U
}

TEST(Polyhedron, RejectsNonPlanarInvertedAndBrokenModels) {
  Polyhedron box = MakeBox({0.1, 0.1, 0.1});
  box.vertices[box.faces[1][0]].z() += 1e-4;  // bend the top
  EXPECT_NE(CheckPolyhedron(box, 1e-9).find("is not planar"), std::string::npos) << CheckPolyhedron(box, 1e-9);
  Polyhedron inverted = MakeBox({0.1, 0.1, 0.1});
  for (auto& f : inverted.faces) std::reverse(f.begin(), f.end());
  EXPECT_NE(CheckPolyhedron(inverted, 1e-9).find("counter-clockwise"), std::string::npos);
  Polyhedron broken = MakeBox({0.1, 0.1, 0.1});
  broken.faces[2].push_back(99);
  EXPECT_NE(CheckPolyhedron(broken, 1e-9).find("refers to vertex 99"), std::string::npos);
}

TEST(FaceOverlap, StickOnCastleNotchFloor) {
  const Polyhedron castle = testing::Castle(0.08, 0.04, 0.02, 0.02, 0.06);
  const Polyhedron stick = MakeBox({0.02, 0.2, 0.04});
  const Matrix4d wMc = Matrix4d::Identity();
  const Matrix4d wMs = testing::Pose(0, 0, 0.02);
  const auto patches = FindFaceContacts(stick, wMs, castle, wMc, {});
  // Bottom on the notch floor, both sides against the notch walls.
  ASSERT_EQ(patches.size(), 3u);
  for (const FacePatch& p : patches) {
    EXPECT_EQ(p.points.size(), 4u);
    EXPECT_LE(p.max_gap, 1e-15);
  }
  const FacePatch& bottom = patches[0];
  EXPECT_EQ(bottom.face, 0);
  EXPECT_NEAR(bottom.width, 0.02, 1e-12);  // notch width (the stick is longer than the castle)
}

TEST(FaceOverlap, NonConvexFacesOverlapExactly) {
  // Two U-shaped front faces, one shifted half a prong over the other: the convex hull of their intersection.
  const Polyhedron a = testing::Castle(0.08, 0.04, 0.02, 0.02, 0.06);
  const Matrix4d wMa = Matrix4d::Identity();
  // b's back face (+y) against a's front face (−y): b sits in front of a, shifted 0.05 in x.
  const Matrix4d wMb = testing::Pose(0.05, -0.06, 0);
  const auto patch = FaceOverlap(a, wMa, 0, a, wMb, 1, 0.0);
  ASSERT_TRUE(patch.has_value());
  // Overlap of x ∈ [−0.04, 0.04] with [0.01, 0.09] minus notches: x from 0.01 to 0.04 (b's notch is at
  // 0.04..0.06): hull spans x ∈ [0.01, 0.04], z ∈ [0, 0.04].
  double xmin = 1, xmax = -1;
  for (const Vector3d& p : patch->points) {
    const Vector3d w = (wMb * p.homogeneous()).head<3>();
    xmin = std::min(xmin, w.x());
    xmax = std::max(xmax, w.x());
  }
  EXPECT_NEAR(xmin, 0.01, 1e-12);
  EXPECT_NEAR(xmax, 0.04, 1e-12);
}

TEST(FaceOverlap, EdgeContactsAndFarFacesAreNotFaceContacts) {
  const Polyhedron box = MakeBox({0.04, 0.04, 0.04});
  // Side by side sharing only an edge line on top of each other's corner: x-adjacent, y-shifted by the full width.
  EXPECT_TRUE(FindFaceContacts(box, testing::Pose(0.04, 0.04, 0), box, Matrix4d::Identity(), {}).empty());
  // Stacked but 5 mm apart: above the distance threshold.
  EXPECT_TRUE(FindFaceContacts(box, testing::Pose(0, 0, 0.045), box, Matrix4d::Identity(), {}).empty());
  // Stacked and tilted 5°: above the angle threshold.
  EXPECT_TRUE(
      FindFaceContacts(box, testing::Pose(0, 0, 0.04) * DeltaTransform((Vector6d() << 0, 0, 0, 0.087, 0, 0).finished()),
                       box, Matrix4d::Identity(), {})
          .empty());
  // Stacked with a 1 mm gap and a 1° tilt: a face contact with a 4-point region.
  const auto found = FindFaceContacts(
      box, testing::Pose(0, 0, 0.041) * DeltaTransform((Vector6d() << 0, 0, 0, 0.0175, 0, 0).finished()), box,
      Matrix4d::Identity(), {});
  ASSERT_EQ(found.size(), 1u);
  EXPECT_EQ(found[0].points.size(), 4u);
}

}  // namespace
}  // namespace visco::face_contact
