// The paper's three examples (Suehiro & Ikeuchi §5.1–5.3) from exact geometry plus seeded noise: the iterative mode
// makes the paper's trials, every residue ends ≤ 1e-9 m, the constrained degrees of freedom match the ground truth,
// the redundant ones keep their observed values, and the robot's disassembly/re-assembly steps are the paper's.

#include "tests/face_contact/apo_examples.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cstdio>
#include <numbers>

#include "face_contact/assembly_plan.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;
using Eigen::Vector3d;
using testing::Example;

constexpr double kResidue = 1e-9;
// Second-order effects of the noise (2e-4 m, 1.5e-3 rad) on directions the contacts do not constrain: far below
// the noise itself and below the 0.5 mm – 0.25 m drifts a wrong rank produces (docs/semantics.md).
constexpr double kKeepT = 2e-6;
constexpr double kKeepR = 2e-5;

std::vector<std::vector<int>> Trials(const ApoStep& step) {
  std::vector<std::vector<int>> out;
  for (const ApoTrial& t : step.trials) {
    std::vector<int> ops;
    for (int o : t.operations) ops.push_back(o + 1);
    out.push_back(ops);
  }
  return out;
}

Matrix4d Relative(const Matrix4d& a, const Matrix4d& b) { return RigidInverse(a) * b; }

// The pose of `b` in `a`'s frame must match the truth except for a translation along `free_axis` of a's frame
// (−1: none free).
void ExpectRelative(const Matrix4d& a, const Matrix4d& b, const Matrix4d& truth_a, const Matrix4d& truth_b,
                    int free_axis, const std::string& what) {
  const Matrix4d got = Relative(a, b);
  const Matrix4d want = Relative(truth_a, truth_b);
  EXPECT_LT((got.block<3, 3>(0, 0) - want.block<3, 3>(0, 0)).cwiseAbs().maxCoeff(), kResidue) << what;
  for (int i = 0; i < 3; ++i) {
    if (i == free_axis) continue;
    EXPECT_NEAR(got(i, 3), want(i, 3), kResidue) << what << " axis " << i;
  }
}

// The object rests flat on the table top z = 0 with its bottom at z = 0 (frame at the bottom).
void ExpectOnTable(const Matrix4d& pose, const std::string& what) {
  EXPECT_NEAR(pose(2, 3), 0, kResidue) << what;
  EXPECT_NEAR(pose(2, 2), 1, kResidue) << what;
}

ApoOptions Options(ApoMode mode) {
  ApoOptions options;
  options.mode = mode;
  return options;
}

void ExpectAllHold(const ApoResult& result) {
  for (size_t r = 0; r < result.relations.size(); ++r) {
    EXPECT_LE(result.relations[r].corrected_residue, kResidue) << "R" << r + 1;
  }
  for (const ApoStep& s : result.steps) {
    if (s.accepted < 0) continue;
    const SolveReport& rep = s.trials[s.accepted].report;
    EXPECT_LE(rep.null_space_component, 1e-9) << rep.message;
    EXPECT_GT(rep.rank_gap, 1e3) << rep.message;
  }
}

class Examples : public ::testing::TestWithParam<unsigned> {};

TEST_P(Examples, CastlesAndStickIterative) {
  const Example ex = testing::CastlesAndStick(GetParam());
  const ApoResult result = PlanFromObservation(ex.observation, Options(ApoMode::kIterative));
  ASSERT_EQ(result.steps.size(), 3u);
  for (size_t i = 0; i < result.steps.size(); ++i) EXPECT_EQ(Trials(result.steps[i]), ex.expected_trials[i]) << i;
  EXPECT_FALSE(result.steps[2].trials[0].success);
  EXPECT_EQ(result.steps[2].trials[0].report.status, SolveStatus::kInconsistent);
  // Residue of T3 alone: the tunnel is 1 mm too narrow, least squares shares it.
  EXPECT_GT(result.steps[2].trials[0].max_relation_residue, 1e-4);
  ExpectAllHold(result);
  const auto poses = FinalPoses(ex.observation, result, true);
  const auto observed = FinalPoses(ex.observation, result, false);
  const Matrix4d &c1 = *poses[1], &c2 = *poses[2], &stick = *poses[3];
  ExpectOnTable(c1, "castle1");
  ExpectRelative(c1, c2, ex.truth[0], ex.truth[1], 1, "castle2 in castle1 (y free)");
  ExpectRelative(c1, stick, ex.truth[0], ex.truth[2], 1, "stick in castle1 (y free)");
  // Redundant degrees of freedom keep the observed values: castle1's x, y and heading (corrected alone at step 1),
  // castle2's and the stick's position along the tunnel.
  EXPECT_NEAR(c1(0, 3), (*observed[1])(0, 3), kKeepT);
  EXPECT_NEAR(c1(1, 3), (*observed[1])(1, 3), kKeepT);
  EXPECT_NEAR(std::atan2(c1(1, 0), c1(0, 0)), std::atan2((*observed[1])(1, 0), (*observed[1])(0, 0)), kKeepR);
  EXPECT_NEAR(c2(1, 3), (*observed[2])(1, 3), kKeepT);
  EXPECT_NEAR(stick(1, 3), (*observed[3])(1, 3), kKeepT);
  // The constrained x of castle2 moved back by the human's 1 mm.
  EXPECT_NEAR(c2(0, 3) - (*observed[2])(0, 3), -testing::kHumanError, 5e-4);
  // Robot: disassemble castle2 (undo step 2), place it with T2', insert the stick with T3' (Fig. 11).
  const auto& robot = result.steps[2].robot;
  ASSERT_EQ(robot.size(), 3u);
  EXPECT_EQ(robot[0].kind, RobotAction::Kind::kUndoPlace);
  EXPECT_EQ(robot[0].operation, 1);
  EXPECT_FALSE(robot[0].pose.has_value());  // castle2 was not in the scene before step 2: take it away
  EXPECT_EQ(robot[1].kind, RobotAction::Kind::kPlace);
  EXPECT_EQ(robot[1].operation, 1);
  EXPECT_TRUE(robot[1].corrected);
  EXPECT_EQ(robot[2].operation, 2);
  EXPECT_TRUE(robot[2].corrected);
}

TEST_P(Examples, SubAssemblyIterative) {
  const Example ex = testing::SubAssembly(GetParam());
  const ApoResult result = PlanFromObservation(ex.observation, Options(ApoMode::kIterative));
  ASSERT_EQ(result.steps.size(), 5u);
  for (size_t i = 0; i < result.steps.size(); ++i) EXPECT_EQ(Trials(result.steps[i]), ex.expected_trials[i]) << i;
  // Candidates at step 5 are T5, T4, T3, T2, T1 (T3 and T4 reached through the stick's ODL T5·T3⁻¹·T4).
  EXPECT_EQ(result.steps[4].candidates, (std::vector<int>{4, 3, 2, 1, 0}));
  ExpectAllHold(result);
  const auto poses = FinalPoses(ex.observation, result, true);
  const Matrix4d &c1 = *poses[1], &c2 = *poses[2], &cube = *poses[3], &stick = *poses[4];
  ExpectOnTable(c1, "castle1");
  ExpectOnTable(c2, "castle2");
  // Castle2 in castle1's frame: only the slide along the notch (castle x axis is world y... the notch runs along
  // castle y, world x) is free.
  ExpectRelative(c1, c2, ex.truth[0], ex.truth[1], 1, "castle2 in castle1 (notch axis free)");
  ExpectRelative(c1, stick, ex.truth[0], ex.truth[4] * RigidInverse(ex.truth[2]) * ex.truth[3], 1, "stick in castle1");
  ExpectRelative(stick, cube, ex.truth[3], ex.truth[2], 1, "cube on the stick (slide along the stick free)");
  // Robot (Fig. 14): undo steps 4, 3, 2; redo 2 (castle2 with T2'), 3, 4, 5.
  std::vector<std::pair<RobotAction::Kind, int>> got;
  for (const RobotAction& a : result.steps[4].robot) got.emplace_back(a.kind, a.operation + 1);
  using K = RobotAction::Kind;
  EXPECT_EQ(got, (std::vector<std::pair<K, int>>{{K::kUndoPlace, 4},
                                                 {K::kUndoPlace, 3},
                                                 {K::kUndoPlace, 2},
                                                 {K::kPlace, 2},
                                                 {K::kPlace, 3},
                                                 {K::kPlace, 4},
                                                 {K::kPlace, 5}}));
}

TEST_P(Examples, DisappearedRelationIterative) {
  const Example ex = testing::DisappearedRelation(GetParam());
  const ApoResult result = PlanFromObservation(ex.observation, Options(ApoMode::kIterative));
  ASSERT_EQ(result.steps.size(), 5u);
  for (size_t i = 0; i < result.steps.size(); ++i) EXPECT_EQ(Trials(result.steps[i]), ex.expected_trials[i]) << i;
  EXPECT_EQ(result.steps[4].candidates, (std::vector<int>{4, 2, 1, 0}));  // T5, T3, T2, T1; not T4 (the removal)
  // The castle2–cube relation disappeared at step 4 and is still an arc.
  bool kept = false;
  for (const Relation& r : result.relations) {
    kept = kept || (r.face_object == 3 && r.vertex_object == 2 && r.disappeared_by == 3);
  }
  EXPECT_TRUE(kept);
  ExpectAllHold(result);
  const auto poses = FinalPoses(ex.observation, result, true);
  EXPECT_FALSE(poses[2].has_value());  // the cube was removed
  const Matrix4d &c1 = *poses[1], &c2 = *poses[3], &stick = *poses[4];
  ExpectRelative(c1, c2, ex.truth[0], ex.truth[2], 1, "castle2 in castle1");
  ExpectRelative(c1, stick, ex.truth[0], ex.truth[4], 1, "stick in castle1");
  // The cube (T2') still touches castle2 (T3'): the disappeared relation holds with the corrected parameters.
  const Matrix4d cube = result.corrected[OperationParam(result, 1)];
  ExpectRelative(c2, cube, ex.truth[2], ex.truth[1], 1, "cube against castle2 (slide along the face free)");
  // Robot (Fig. 17): undo 4 (put the cube back), undo 3, undo 2; redo 2, 3, 4 (remove the cube), 5.
  std::vector<std::pair<RobotAction::Kind, int>> got;
  for (const RobotAction& a : result.steps[4].robot) got.emplace_back(a.kind, a.operation + 1);
  using K = RobotAction::Kind;
  EXPECT_EQ(got, (std::vector<std::pair<K, int>>{{K::kUndoRemove, 4},
                                                 {K::kUndoPlace, 3},
                                                 {K::kUndoPlace, 2},
                                                 {K::kPlace, 2},
                                                 {K::kPlace, 3},
                                                 {K::kRemove, 4},
                                                 {K::kPlace, 5}}));
}

TEST_P(Examples, AllAtOnceSatisfiesEveryContact) {
  for (const Example& ex : {testing::CastlesAndStick(GetParam()), testing::SubAssembly(GetParam()),
                            testing::DisappearedRelation(GetParam())}) {
    SCOPED_TRACE(ex.name);
    const ApoResult result = PlanFromObservation(ex.observation, Options(ApoMode::kAllAtOnce));
    ASSERT_EQ(result.steps.size(), 1u);
    ASSERT_EQ(result.steps[0].trials.size(), 1u);
    EXPECT_TRUE(result.steps[0].trials[0].success);
    ExpectAllHold(result);
    // Every stable-supported object is flat on the table and the human's 1 mm error is gone: castle2 lines up with
    // castle1 in the constrained directions.
    const auto poses = FinalPoses(ex.observation, result, true);
    const int c2 = ex.name.starts_with("5.3") ? 3 : 2;
    const int c2_op = ex.name.starts_with("5.3") ? 2 : 1;
    ExpectRelative(*poses[1], *poses[c2], ex.truth[0], ex.truth[c2_op], 1, "castle2 in castle1");
  }
}

// docs/semantics.md's warning, reproduced on §5.1 all at once: at the noisy observation the redundant directions have
// small but non-zero singular values, so a default pseudo-inverse threshold sees a higher rank than the contacts'
// structural rank (measured where they hold), and the paper's plain iteration with it drifts along redundant
// directions. Our correction has no null-space component.
TEST(Examples51, RankAtObservationExceedsStructuralRank) {
  const Example ex = testing::CastlesAndStick(1);
  ApoOptions options = Options(ApoMode::kAllAtOnce);
  const ApoResult result = PlanFromObservation(ex.observation, options);
  const ApoTrial& trial = result.steps[0].trials[0];
  ContactProblem problem;
  problem.params = result.observed;
  for (int op : trial.operations) problem.variables.push_back(OperationParam(result, op));
  for (const Relation& r : result.relations) {
    for (const FacePatch& p : r.patches) {
      problem.groups.push_back({r.chain, FacePlane(ex.observation.objects[r.face_object].model, p.face), p.points, -1});
    }
  }
  const Eigen::MatrixXd jac = Jacobian(problem, Eigen::VectorXd::Zero(6 * static_cast<int>(problem.variables.size())));
  Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd> cod(jac);  // Eigen's default threshold
  EXPECT_GT(cod.rank(), trial.report.rank);
  EXPECT_EQ(trial.report.unknowns, 18);
  EXPECT_LE(trial.report.null_space_component, 1e-12);
  // The paper's iteration with that rank: contacts hold, but the correction is longer (it slid along redundant
  // directions) than ours.
  Eigen::VectorXd q = Eigen::VectorXd::Zero(jac.cols());
  for (int it = 0; it < 50; ++it) {
    const Eigen::VectorXd e = Residues(problem, q);
    if (e.cwiseAbs().maxCoeff() < 1e-12) break;
    q -= Eigen::CompleteOrthogonalDecomposition<Eigen::MatrixXd>(Jacobian(problem, q)).solve(e);
  }
  EXPECT_LT(Residues(problem, q).cwiseAbs().maxCoeff(), 1e-9);
  Eigen::VectorXd p = q;
  for (Eigen::Index i = 0; i < p.size(); ++i) p[i] *= i % 6 < 3 ? 1.0 : 0.1;
  EXPECT_GT(p.norm(), trial.report.correction_norm * (1 + 1e-6));
  std::printf("rank at observation %ld, structural %d; plain-iteration correction %.6g vs smallest %.6g\n",
              static_cast<long>(cod.rank()), trial.report.rank, p.norm(), trial.report.correction_norm);
}

INSTANTIATE_TEST_SUITE_P(Seeds, Examples, ::testing::Values(1u, 2u, 3u, 4u, 5u));

}  // namespace
}  // namespace visco::face_contact
