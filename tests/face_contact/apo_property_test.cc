// Property tests on random consistent assemblies with noise: boxes stacked in columns on a table and boxes pushed
// against each other's sides, observed with seeded noise. Both modes must make every contact exact, recover the
// constrained degrees of freedom of the ground truth, and return the smallest correction, which we check against a
// slow obvious reference: finite-difference Jacobians, their null space by full-pivoting LU, and local perturbations
// along the contact manifold that must not shorten the correction.

#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <random>

#include "face_contact/assembly_plan.h"
#include "tests/face_contact/apo_examples.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

struct Scene {
  ApoObservation observation;
  std::vector<Matrix4d> truth;                  // per operation
  std::vector<std::pair<int, int>> side_pairs;  // (a, b) operations: b pushed against a's +x face
  std::vector<std::pair<int, int>> stacked;     // (below, above) operations
};

Scene RandomScene(unsigned seed, int boxes) {
  std::mt19937_64 rng(seed);
  auto u = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  Scene s;
  testing::Noise noise(seed * 7919u + 1u, 2e-4, 1.5e-3);
  testing::AddObject(s.observation, "table", MakeBox({2, 2, 0.05}), true, testing::Pose(0, 0, -0.05));
  struct Column {
    int top;        // operation
    Vector3d size;  // of the top box
    double top_z;
    bool stackable;
    bool side_free;
  };
  std::vector<Column> columns;
  int cell = 0;
  for (int i = 0; i < boxes; ++i) {
    Vector3d size(u(0.03, 0.08), u(0.03, 0.08), u(0.02, 0.06));
    const double choice = u(0, 1);
    Matrix4d truth;
    std::vector<int> stackable;
    for (size_t c = 0; c < columns.size(); ++c) {
      if (columns[c].stackable) stackable.push_back(static_cast<int>(c));
    }
    std::vector<int> side_free;
    for (size_t c = 0; c < columns.size(); ++c) {
      if (columns[c].side_free) side_free.push_back(static_cast<int>(c));
    }
    if (choice < 0.4 && !stackable.empty()) {
      Column& col = columns[stackable[static_cast<size_t>(u(0, 1) * static_cast<double>(stackable.size()))]];
      truth = s.truth[col.top] * testing::Pose(u(-0.008, 0.008), u(-0.008, 0.008), col.size.z(), u(-30, 30));
      s.stacked.emplace_back(col.top, i);
      col.top = i;
      col.size = size;
      col.side_free = false;
    } else if (choice < 0.6 && !side_free.empty()) {
      Column& col = columns[side_free[static_cast<size_t>(u(0, 1) * static_cast<double>(side_free.size()))]];
      size.z() = std::min(size.z(), col.size.z() - 0.005);
      size.y() = std::max(size.y(), 0.03);
      truth = s.truth[col.top] * testing::Pose(col.size.x() / 2 + size.x() / 2, u(-0.005, 0.005), 0);
      s.side_pairs.emplace_back(col.top, i);
      col.side_free = false;  // one side neighbour per column base
      columns.push_back({i, size, size.z(), false, false});
    } else {
      truth = testing::Pose((cell % 5) * 0.3 - 0.6, (cell / 5) * 0.3 - 0.6, 0, u(-30, 30));
      ++cell;
      columns.push_back({i, size, size.z(), true, true});
    }
    const int object = testing::AddObject(s.observation, "box" + std::to_string(i), MakeBox(size));
    ApoOperation op;
    op.object = object;
    op.observed = noise(truth);
    s.observation.operations.push_back(op);
    s.truth.push_back(truth);
  }
  return s;
}

// Reference: the problem rebuilt from the result (not from the solver's internals) with every corrected operation
// variable, q = the corrections, and the Jacobian by central differences.
struct Reference {
  ContactProblem problem;
  VectorXd q;
};

Reference Rebuild(const ApoObservation& obs, const ApoResult& result, const std::vector<int>& operations) {
  Reference ref;
  ref.problem.params = result.observed;
  for (int op : operations) ref.problem.variables.push_back(OperationParam(result, op));
  for (const Relation& r : result.relations) {
    for (const FacePatch& p : r.patches) {
      ref.problem.groups.push_back({r.chain, FacePlane(obs.objects[r.face_object].model, p.face), p.points, -1});
    }
  }
  ref.q = VectorXd::Zero(6 * static_cast<Eigen::Index>(operations.size()));
  for (size_t v = 0; v < operations.size(); ++v) {
    const int p = OperationParam(result, operations[v]);
    ref.q.segment<6>(6 * static_cast<Eigen::Index>(v)) =
        DeltaParameters(RigidInverse(result.observed[p]) * result.corrected[p]);
  }
  return ref;
}

MatrixXd FiniteDifferenceJacobian(const ContactProblem& problem, const VectorXd& q) {
  MatrixXd jac(EquationCount(problem), q.size());
  for (Eigen::Index c = 0; c < q.size(); ++c) {
    VectorXd qp = q, qm = q;
    qp[c] += 1e-7;
    qm[c] -= 1e-7;
    jac.col(c) = (Residues(problem, qp) - Residues(problem, qm)) / 2e-7;
  }
  return jac;
}

VectorXd Weights(Eigen::Index n) {
  VectorXd w(n);
  for (Eigen::Index i = 0; i < n; ++i) w[i] = i % 6 < 3 ? 1.0 : 0.1;  // characteristic length 0.1 m
  return w;
}

// Newton projection back onto f = 0 keeping the step in the row space (plain least squares, slow is fine).
VectorXd ProjectToManifold(const ContactProblem& problem, VectorXd q) {
  for (int it = 0; it < 30; ++it) {
    const VectorXd e = Residues(problem, q);
    if (e.cwiseAbs().maxCoeff() < 1e-14) break;
    const MatrixXd jac = FiniteDifferenceJacobian(problem, q);
    q -= jac.completeOrthogonalDecomposition().solve(e);
  }
  return q;
}

void CheckSmallest(const ApoObservation& obs, const ApoResult& result, const std::vector<int>& operations,
                   std::mt19937_64& rng) {
  const Reference ref = Rebuild(obs, result, operations);
  ASSERT_LE(Residues(ref.problem, ref.q).cwiseAbs().maxCoeff(), 1e-9);
  const VectorXd w = Weights(ref.q.size());
  const VectorXd p = ref.q.cwiseProduct(w);
  const MatrixXd jp = FiniteDifferenceJacobian(ref.problem, ref.q) * w.cwiseInverse().asDiagonal();
  Eigen::FullPivLU<MatrixXd> lu(jp);
  lu.setThreshold(1e-6);
  const MatrixXd kernel = lu.kernel();
  if (kernel.cols() == 0 || kernel.norm() == 0) return;
  const MatrixXd basis = kernel.householderQr().householderQ() * MatrixXd::Identity(kernel.rows(), kernel.cols());
  // First-order condition: no component of the (weighted) correction along the null space.
  EXPECT_LT((basis.transpose() * p).norm(), 1e-6 * std::max(1.0, p.norm()) + 1e-9) << "kernel " << kernel.cols();
  // Second: moving along the contact manifold does not shorten the correction.
  std::normal_distribution<double> n01;
  for (int k = 0; k < 5; ++k) {
    VectorXd dir(basis.cols());
    for (Eigen::Index i = 0; i < dir.size(); ++i) dir[i] = n01(rng);
    const VectorXd moved = ProjectToManifold(ref.problem, ref.q + (basis * dir.normalized() * 1e-4).cwiseQuotient(w));
    EXPECT_GE(moved.cwiseProduct(w).norm(), p.norm() - 1e-12);
  }
}

void CheckTruth(const Scene& s, const ApoResult& result) {
  const auto poses = FinalPoses(s.observation, result, true);
  for (size_t i = 0; i < s.truth.size(); ++i) {
    const Matrix4d& got = *poses[i + 1];
    EXPECT_NEAR(got(2, 2), 1, 1e-9) << "box" << i << " flat";
    EXPECT_NEAR(got(2, 3), s.truth[i](2, 3), 1e-9) << "box" << i << " height";
  }
  for (const auto& [a, b] : s.side_pairs) {
    const Matrix4d got = RigidInverse(*poses[a + 1]) * *poses[b + 1];
    const Matrix4d want = RigidInverse(s.truth[a]) * s.truth[b];
    EXPECT_LT((got.block<3, 3>(0, 0) - want.block<3, 3>(0, 0)).cwiseAbs().maxCoeff(), 1e-9) << a << "|" << b;
    EXPECT_NEAR(got(0, 3), want(0, 3), 1e-9) << a << "|" << b << " side distance";
  }
}

TEST(ApoProperty, RandomAssembliesBothModes) {
  std::mt19937_64 rng(99);
  int side_pairs = 0, stacked = 0;
  for (unsigned seed = 1; seed <= 25; ++seed) {
    const Scene s = RandomScene(seed, 3 + static_cast<int>(seed % 6));
    side_pairs += static_cast<int>(s.side_pairs.size());
    stacked += static_cast<int>(s.stacked.size());
    for (ApoMode mode : {ApoMode::kIterative, ApoMode::kAllAtOnce}) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << (mode == ApoMode::kIterative ? " iterative" : " all"));
      ApoOptions options;
      options.mode = mode;
      ApoResult result;
      ASSERT_NO_THROW(result = PlanFromObservation(s.observation, options));
      // Every box touches the table or another box: one relation per placement at least.
      EXPECT_GE(result.relations.size(), s.truth.size());
      for (const Relation& r : result.relations) EXPECT_LE(r.corrected_residue, 1e-9);
      for (const ApoStep& step : result.steps) {
        if (step.accepted < 0) continue;
        const SolveReport& rep = step.trials[step.accepted].report;
        EXPECT_LE(rep.null_space_component, 1e-9) << rep.message << " gap " << rep.rank_gap;
        EXPECT_GT(rep.rank_gap, 1e3) << rep.message;
      }
      CheckTruth(s, result);
      if (mode == ApoMode::kAllAtOnce && !result.steps[0].trials.empty()) {
        CheckSmallest(s.observation, result, result.steps[0].trials[0].operations, rng);
      }
    }
  }
  // The generator really made both kinds of contact.
  EXPECT_GT(side_pairs, 5);
  EXPECT_GT(stacked, 5);
}

}  // namespace
}  // namespace visco::face_contact
