// The vision-facing call: observed poses made flush.

#include "face_contact/flush_poses.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include "tests/face_contact/apo_examples.h"

namespace visco::face_contact {
namespace {

using Eigen::Isometry3d;
using Eigen::Matrix4d;

Isometry3d Iso(const Matrix4d& m) {
  Isometry3d iso;
  iso.matrix() = m;
  return iso;
}

TEST(MakeFlush, StackOnTableBecomesFlushAndKeepsFreeDirections) {
  testing::Noise noise(3, 5e-4, 5e-3);
  const Matrix4d table = testing::Pose(0, 0, -0.05);
  const Matrix4d a = testing::Pose(0.1, 0.05, 0, 20);
  const Matrix4d b = testing::Pose(0.11, 0.04, 0.04, 35);  // on a, overhanging, rotated
  std::vector<FlushObject> objects = {{"table", MakeBox({1, 1, 0.05}), Iso(table), true},
                                      {"a", MakeBox({0.08, 0.06, 0.04}), Iso(noise(a))},
                                      {"b", MakeBox({0.05, 0.05, 0.03}), Iso(noise(b))}};
  const FlushResult result = MakeFlush(objects);
  ASSERT_TRUE(result.ok) << result.message;
  EXPECT_EQ(result.contacts.size(), 2u);  // a on the table, b on a
  EXPECT_LE(result.report.max_residue, 1e-9);
  EXPECT_LE(result.report.null_space_component, 1e-9);
  EXPECT_TRUE(result.poses[0].isApprox(objects[0].pose, 0));  // stable: untouched
  for (int i : {1, 2}) {
    EXPECT_NEAR(result.poses[i].matrix()(2, 2), 1, 1e-12) << i;  // flat
    // Free directions (x, y, heading) keep the observed values to second order.
    EXPECT_NEAR(result.poses[i].translation().x(), objects[i].pose.translation().x(), 2e-5);
    EXPECT_NEAR(result.poses[i].translation().y(), objects[i].pose.translation().y(), 2e-5);
  }
  EXPECT_NEAR(result.poses[1].translation().z(), 0, 1e-12);
  EXPECT_NEAR(result.poses[2].translation().z(), 0.04, 1e-12);
}

TEST(MakeFlush, NothingTouchingLeavesPosesAlone) {
  std::vector<FlushObject> objects = {{"table", MakeBox({1, 1, 0.05}), Iso(testing::Pose(0, 0, -0.05)), true},
                                      {"floating", MakeBox({0.1, 0.1, 0.1}), Iso(testing::Pose(0, 0, 0.2))}};
  const FlushResult result = MakeFlush(objects);
  EXPECT_TRUE(result.ok);
  EXPECT_TRUE(result.contacts.empty());
  EXPECT_TRUE(result.poses[1].isApprox(objects[1].pose, 0));
}

TEST(MakeFlush, BadModelThrows) {
  Polyhedron bad = MakeBox({0.1, 0.1, 0.1});
  bad.faces[0].resize(2);
  std::vector<FlushObject> objects = {{"bad", bad, Isometry3d::Identity()}};
  EXPECT_THROW(MakeFlush(objects), std::invalid_argument);
}

}  // namespace
}  // namespace visco::face_contact
