// Face contact equations (Suehiro & Ikeuchi §2, §7): the variable matrix, its analytic derivatives (eqs. 27–32),
// the Jacobian against finite differences, ODL algebra, and the solver's smallest-correction certificate.

#include "face_contact/face_contact.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "face_contact/polyhedron.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

Vector6d RandomQ(std::mt19937_64& rng, double t, double r) {
  std::uniform_real_distribution<double> u(-1, 1);
  Vector6d q;
  for (int i = 0; i < 6; ++i) q[i] = (i < 3 ? t : r) * u(rng);
  return q;
}

Matrix4d RandomPose(std::mt19937_64& rng) { return DeltaTransform(RandomQ(rng, 0.5, 3.0)); }

TEST(DeltaTransform, IdentityAtZeroAndPaperOrder) {
  EXPECT_TRUE(DeltaTransform(Vector6d::Zero()).isIdentity(0));
  Vector6d q;
  q << 0.1, 0.2, 0.3, 0.4, 0.5, 0.6;
  // P(x,y,z)·Rx(α)·Ry(β)·Rz(γ) (eq. 4).
  const Eigen::Matrix3d r = (Eigen::AngleAxisd(0.4, Vector3d::UnitX()) * Eigen::AngleAxisd(0.5, Vector3d::UnitY()) *
                             Eigen::AngleAxisd(0.6, Vector3d::UnitZ()))
                                .toRotationMatrix();
  const Matrix4d m = DeltaTransform(q);
  EXPECT_TRUE((m.block<3, 3>(0, 0).isApprox(r, 1e-14)));
  EXPECT_TRUE((m.block<3, 1>(0, 3).isApprox(Vector3d(0.1, 0.2, 0.3), 1e-15)));
  EXPECT_TRUE(DeltaParameters(m).isApprox(q, 1e-14));
}

TEST(DeltaTransform, DerivativesAtZeroAreEquations27To32) {
  // The matrices printed in §7, row by row.
  const double eq[6][16] = {
      {0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},   // (27) x
      {0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0},   // (28) y
      {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 1, 0, 0, 0, 0},   // (29) z
      {0, 0, 0, 0, 0, 0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 0},  // (30) α
      {0, 0, 1, 0, 0, 0, 0, 0, -1, 0, 0, 0, 0, 0, 0, 0},  // (31) β
      {0, -1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0},  // (32) γ
  };
  for (int j = 0; j < 6; ++j) {
    const Matrix4d expected = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(eq[j]);
    EXPECT_TRUE(DeltaTransformDerivative(Vector6d::Zero(), j).isApprox(expected, 0)) << "eq. " << 27 + j;
    // ∂ΔT⁻¹/∂q_j = −∂ΔT/∂q_j at zero (the second form of each equation).
    const double h = 1e-7;
    Vector6d dq = Vector6d::Zero();
    dq[j] = h;
    const Matrix4d fd = (RigidInverse(DeltaTransform(dq)) - RigidInverse(DeltaTransform(-dq))) / (2 * h);
    EXPECT_LT((fd + expected).cwiseAbs().maxCoeff(), 1e-8) << "eq. " << 27 + j << " inverse";
  }
}

TEST(DeltaTransform, DerivativesMatchFiniteDifferencesAnywhere) {
  std::mt19937_64 rng(7);
  for (int trial = 0; trial < 50; ++trial) {
    const Vector6d q = RandomQ(rng, 0.3, 1.2);
    for (int j = 0; j < 6; ++j) {
      const double h = 1e-6;
      Vector6d dq = Vector6d::Zero();
      dq[j] = h;
      const Matrix4d fd = (DeltaTransform(q + dq) - DeltaTransform(q - dq)) / (2 * h);
      EXPECT_LT((fd - DeltaTransformDerivative(q, j)).cwiseAbs().maxCoeff(), 1e-9);
    }
  }
}

TEST(Odl, InverseAndCancellation) {
  const Odl d = {{3, false}, {1, true}, {2, false}};  // T3·T1⁻¹·T2
  EXPECT_EQ(InverseOdl(d), (Odl{{2, true}, {1, false}, {3, true}}));
  EXPECT_TRUE(ConcatenateOdl(InverseOdl(d), d).empty());
  // Paper §3.3.2 R8: ODL_cube2 = T6·T5⁻¹·T2 against the table T0: e = n·T2⁻¹·T5·T6⁻¹·T0·v.
  const Odl cube2 = {{6, false}, {5, true}, {2, false}};
  EXPECT_EQ(ConcatenateOdl(InverseOdl(cube2), {{0, false}}), (Odl{{2, true}, {5, false}, {6, true}, {0, false}}));
}

// Random chains with repeated and inverted factors: the analytic Jacobian equals central differences.
TEST(Jacobian, MatchesFiniteDifferencesOnRandomChains) {
  std::mt19937_64 rng(11);
  std::uniform_int_distribution<int> pick(0, 4);
  for (int trial = 0; trial < 30; ++trial) {
    ContactProblem problem;
    for (int k = 0; k < 5; ++k) problem.params.push_back(RandomPose(rng));
    problem.variables = {4, 1, 2};  // any order; param 0 and 3 constant
    for (int g = 0; g < 6; ++g) {
      ContactGroup group;
      const int len = 1 + pick(rng);
      for (int i = 0; i < len; ++i) group.chain.push_back({pick(rng), pick(rng) % 2 == 0});
      const Vector3d n = Vector3d::Random().normalized();
      group.plane << n, 0.3 * std::uniform_real_distribution<double>(-1, 1)(rng);
      for (int p = 0; p < 3; ++p) group.points.push_back(Vector3d::Random() * 0.2);
      problem.groups.push_back(group);
    }
    VectorXd q(18);
    for (int i = 0; i < 18; ++i) q[i] = std::uniform_real_distribution<double>(-0.3, 0.3)(rng);
    const MatrixXd jac = Jacobian(problem, q);
    ASSERT_EQ(jac.rows(), 18);
    ASSERT_EQ(jac.cols(), 18);
    const double h = 1e-6;
    for (int c = 0; c < 18; ++c) {
      VectorXd qp = q, qm = q;
      qp[c] += h;
      qm[c] -= h;
      const VectorXd fd = (Residues(problem, qp) - Residues(problem, qm)) / (2 * h);
      EXPECT_LT((fd - jac.col(c)).cwiseAbs().maxCoeff(), 1e-8) << "trial " << trial << " column " << c;
    }
    // At q = 0 too (the literal §7 case).
    const MatrixXd jac0 = Jacobian(problem, VectorXd::Zero(18));
    for (int c = 0; c < 18; ++c) {
      VectorXd qp = VectorXd::Zero(18), qm = VectorXd::Zero(18);
      qp[c] = h;
      qm[c] = -h;
      const VectorXd fd = (Residues(problem, qp) - Residues(problem, qm)) / (2 * h);
      EXPECT_LT((fd - jac0.col(c)).cwiseAbs().maxCoeff(), 1e-8);
    }
  }
}

// A box resting on a fixed table, observed tilted and lifted.
struct BoxOnTable {
  ContactProblem problem;
  Matrix4d truth;
};

BoxOnTable MakeBoxOnTable(const Vector6d& noise) {
  BoxOnTable b;
  const Polyhedron box = MakeBox({0.1, 0.06, 0.04});
  Vector6d t;
  t << 0.2, -0.1, 0, 0, 0, 0.7;
  b.truth = DeltaTransform(t);
  b.problem.params = {Matrix4d::Identity(), b.truth * DeltaTransform(noise)};  // table frame: top at z = 0
  b.problem.variables = {1};
  ContactGroup g;
  g.chain = {{1, true}, {0, false}};
  g.plane = FacePlane(box, 0);  // the box's bottom
  for (int v : box.faces[0]) g.points.push_back((b.truth * box.vertices[v].homogeneous()).head<3>());
  b.problem.groups.push_back(g);
  return b;
}

TEST(SolveContacts, BoxOnTableSmallestCorrection) {
  Vector6d noise;
  noise << 3e-4, -2e-4, 1e-3, 0.01, -0.02, 0.015;
  const BoxOnTable b = MakeBoxOnTable(noise);
  const SolveReport r = SolveContacts(b.problem);
  ASSERT_EQ(r.status, SolveStatus::kConverged) << r.message;
  EXPECT_LE(r.max_residue, 1e-12);
  EXPECT_EQ(r.rank, 3);  // z, α, β; the table leaves x, y and the heading free
  EXPECT_GT(r.rank_gap, 1e6);
  EXPECT_LE(r.null_space_component, 1e-12);
  const Matrix4d& c = r.corrected[1];
  EXPECT_NEAR(c(2, 3), 0, 1e-12);
  EXPECT_NEAR(c(2, 2), 1, 1e-12);
  // The corrected box differs from the observed one only by a tilt about its bottom centre and a lift: x and y of
  // the origin keep their observed values to second order (a few µm here), the heading likewise.
  const Matrix4d& obs = b.problem.params[1];
  EXPECT_NEAR(c(0, 3), obs(0, 3), 5e-6);
  EXPECT_NEAR(c(1, 3), obs(1, 3), 5e-6);
  // The answer does not depend on where the iteration starts: the paper's naive step (default pseudo-inverse at
  // every iterate, accumulated) is not what we return, the minimum-norm point is; it satisfies the first-order
  // condition q ∈ row(J) in the weighted metric, which we verify independently here with a full SVD.
  const MatrixXd jac = Jacobian(b.problem, r.q);
  VectorXd w(6);
  w << 1, 1, 1, 10, 10, 10;  // 1 / characteristic length
  const MatrixXd jp = jac * w.asDiagonal();
  const VectorXd p = r.q.cwiseQuotient(w);
  Eigen::JacobiSVD<MatrixXd> svd(jp, Eigen::ComputeFullV);
  const MatrixXd null_basis = svd.matrixV().rightCols(3);
  EXPECT_LT((null_basis.transpose() * p).norm(), 1e-12);
}

TEST(SolveContacts, InconsistentContactsAreReported) {
  // Two parallel faces of one fixed block, 0.05 m apart, and a 0.04 m box that must touch both: impossible.
  ContactProblem problem;
  const Polyhedron box = MakeBox({0.04, 0.04, 0.04});
  problem.params = {Matrix4d::Identity(), Matrix4d::Identity()};
  problem.variables = {1};
  for (double z : {0.0, 0.05}) {
    ContactGroup g;
    g.chain = {{1, true}, {0, false}};
    g.plane = FacePlane(box, z == 0 ? 0 : 1);
    for (double x : {-0.01, 0.01}) {
      for (double y : {-0.01, 0.01}) g.points.emplace_back(x, y, z);
    }
    problem.groups.push_back(g);
  }
  const SolveReport r = SolveContacts(problem);
  EXPECT_EQ(r.status, SolveStatus::kInconsistent) << r.message;
  EXPECT_NEAR(r.max_residue, 0.005, 1e-6);  // least squares shares the 1 cm between the two faces
  EXPECT_NE(r.message.find("cannot all hold"), std::string::npos);
}

TEST(SolveContacts, NothingVariable) {
  ContactProblem problem;
  problem.params = {Matrix4d::Identity()};
  ContactGroup g;
  g.chain = {{0, false}};
  g.plane << 0, 0, 1, 0;
  g.points = {Vector3d(0, 0, 0), Vector3d(1, 0, 0), Vector3d(0, 1, 0)};
  problem.groups.push_back(g);
  EXPECT_EQ(SolveContacts(problem).status, SolveStatus::kConverged);
  problem.groups[0].plane[3] = -0.01;
  EXPECT_EQ(SolveContacts(problem).status, SolveStatus::kInconsistent);
}

}  // namespace
}  // namespace visco::face_contact
