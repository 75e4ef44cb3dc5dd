// Face-contact correction at scale: 50 objects and 200 relations (4 contact vertices each: 800 equations, 300
// unknowns), observed with noise, solved for the smallest correction. Baselines in the same run: one Jacobian
// evaluation and one SVD of the same size (the cost floor of a Newton iteration), and the paper's plain iteration
// (Δq = −J⁺e with Eigen's default pseudo-inverse threshold, accumulated), which converges to a correction that is
// not the smallest. Counters: iterations of both phases, rank, max residue, correction size.
//
// Also the whole pipeline: `visco apo`'s all-at-once mode on a random assembly of 50 boxes (relations found from
// the poses).

#include <benchmark/benchmark.h>

#include <Eigen/Dense>
#include <random>

#include "face_contact/assembly_plan.h"
#include "face_contact/face_contact.h"
#include "tests/face_contact/apo_examples.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;
using Eigen::MatrixXd;
using Eigen::Vector3d;
using Eigen::VectorXd;

// Param 0 is a fixed table; 1..objects move. Each relation: a random plane in object a's frame through a random
// point, four vertices of a 4 cm square on it, given in object b's frame at the ground truth: consistent by
// construction. Observed = truth · ΔT(noise).
ContactProblem RandomSystem(int objects, int relations, unsigned seed) {
  std::mt19937_64 rng(seed);
  auto u = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  std::vector<Matrix4d> truth = {Matrix4d::Identity()};
  for (int i = 0; i < objects; ++i) {
    Vector6d q;
    q << u(-0.5, 0.5), u(-0.5, 0.5), u(0, 0.5), u(-3, 3), u(-1.5, 1.5), u(-3, 3);
    truth.push_back(DeltaTransform(q));
  }
  ContactProblem problem;
  testing::Noise noise(seed + 1, 2e-4, 1.5e-3);
  problem.params.push_back(truth[0]);
  for (int i = 1; i <= objects; ++i) {
    problem.params.push_back(noise(truth[i]));
    problem.variables.push_back(i);
  }
  for (int r = 0; r < relations; ++r) {
    // Every object gets relations; object 0 (the table) appears in some.
    const int a = 1 + r % objects;
    int b = static_cast<int>(u(0, objects + 1));
    if (b == a) b = (b + 1) % (objects + 1);
    const Vector3d n = Vector3d(u(-1, 1), u(-1, 1), u(-1, 1)).normalized();
    const Vector3d c(u(-0.05, 0.05), u(-0.05, 0.05), u(-0.05, 0.05));
    const Vector3d e1 = n.unitOrthogonal();
    const Vector3d e2 = n.cross(e1);
    ContactGroup g;
    g.chain = {{a, true}, {b, false}};
    g.plane << n, -n.dot(c);
    const Matrix4d bMa = RigidInverse(truth[b]) * truth[a];
    for (double s : {-0.02, 0.02}) {
      for (double t : {-0.02, 0.02}) g.points.push_back((bMa * (c + s * e1 + t * e2).homogeneous()).head<3>());
    }
    problem.groups.push_back(g);
  }
  return problem;
}

void BM_Jacobian(benchmark::State& state) {
  const ContactProblem problem = RandomSystem(50, 200, 1);
  const VectorXd q = VectorXd::Zero(300);
  for (auto _ : state) benchmark::DoNotOptimize(Jacobian(problem, q).data());
}
BENCHMARK(BM_Jacobian)->Unit(benchmark::kMillisecond);

void BM_OneSvdBaseline(benchmark::State& state) {
  const ContactProblem problem = RandomSystem(50, 200, 1);
  const MatrixXd jac = Jacobian(problem, VectorXd::Zero(300));
  for (auto _ : state) {
    Eigen::BDCSVD<MatrixXd> svd(jac, Eigen::ComputeThinU | Eigen::ComputeThinV);
    benchmark::DoNotOptimize(svd.singularValues().data());
  }
}
BENCHMARK(BM_OneSvdBaseline)->Unit(benchmark::kMillisecond);

void BM_SolveSmallestCorrection(benchmark::State& state) {
  const ContactProblem problem = RandomSystem(50, 200, 1);
  SolveReport report;
  for (auto _ : state) {
    report = SolveContacts(problem);
    benchmark::DoNotOptimize(report.q.data());
  }
  if (report.status != SolveStatus::kConverged) state.SkipWithError(report.message.c_str());
  state.counters["search_iterations"] = report.search_iterations;
  state.counters["newton_iterations"] = report.newton_iterations;
  state.counters["rank"] = report.rank;
  state.counters["max_residue_m"] = report.max_residue;
  state.counters["correction"] = report.correction_norm;
}
BENCHMARK(BM_SolveSmallestCorrection)->Unit(benchmark::kMillisecond);

// The paper's iteration taken literally with a default pseudo-inverse threshold (Eigen's
// completeOrthogonalDecomposition), accumulated from the observation until the step is tiny.
void BM_PlainNewtonBaseline(benchmark::State& state) {
  const ContactProblem problem = RandomSystem(50, 200, 1);
  int iterations = 0;
  double residue = 0, norm = 0;
  for (auto _ : state) {
    VectorXd q = VectorXd::Zero(300);
    for (iterations = 0; iterations < 100; ++iterations) {
      const VectorXd e = Residues(problem, q);
      residue = e.cwiseAbs().maxCoeff();
      if (residue < 1e-10) break;
      Eigen::BDCSVD<MatrixXd> svd(Jacobian(problem, q), Eigen::ComputeThinU | Eigen::ComputeThinV);
      q -= svd.solve(e);
    }
    VectorXd p = q;
    for (Eigen::Index i = 0; i < p.size(); ++i) p[i] *= i % 6 < 3 ? 1.0 : 0.1;
    norm = p.norm();
    benchmark::DoNotOptimize(q.data());
  }
  state.counters["iterations"] = iterations;
  state.counters["max_residue_m"] = residue;
  state.counters["correction"] = norm;
}
BENCHMARK(BM_PlainNewtonBaseline)->Unit(benchmark::kMillisecond);

// The pipeline: 50 boxes in columns on a table (relations found from the noisy poses), all-at-once.
ApoObservation Columns(int boxes, unsigned seed) {
  std::mt19937_64 rng(seed);
  auto u = [&](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  ApoObservation obs;
  testing::Noise noise(seed, 2e-4, 1.5e-3);
  testing::AddObject(obs, "table", MakeBox({3, 3, 0.05}), true, testing::Pose(0, 0, -0.05));
  std::vector<Matrix4d> tops;
  std::vector<double> heights;
  for (int i = 0; i < boxes; ++i) {
    const Vector3d size(u(0.04, 0.08), u(0.04, 0.08), u(0.02, 0.05));
    Matrix4d truth;
    if (i < 10) {
      truth = testing::Pose((i % 5) * 0.3 - 0.6, (i / 5) * 0.3 - 0.3, 0, u(-30, 30));
      tops.push_back(truth);
      heights.push_back(size.z());
    } else {
      const size_t c = static_cast<size_t>(i % 10);
      truth = tops[c] * testing::Pose(u(-0.008, 0.008), u(-0.008, 0.008), heights[c], u(-30, 30));
      tops[c] = truth;
      heights[c] = size.z();
    }
    const int o = testing::AddObject(obs, "box" + std::to_string(i), MakeBox(size));
    ApoOperation op;
    op.object = o;
    op.observed = noise(truth);
    obs.operations.push_back(op);
  }
  return obs;
}

void BM_ApoAllAtOnce50Boxes(benchmark::State& state) {
  const ApoObservation obs = Columns(50, 3);
  ApoOptions options;
  options.mode = ApoMode::kAllAtOnce;
  ApoResult result;
  for (auto _ : state) {
    result = PlanFromObservation(obs, options);
    benchmark::DoNotOptimize(result.corrected.data());
  }
  state.counters["relations"] = static_cast<double>(result.relations.size());
  const SolveReport& r = result.steps[0].trials[0].report;
  state.counters["search_iterations"] = r.search_iterations;
  state.counters["newton_iterations"] = r.newton_iterations;
  state.counters["rank"] = r.rank;
  state.counters["unknowns"] = r.unknowns;
}
BENCHMARK(BM_ApoAllAtOnce50Boxes)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace visco::face_contact

BENCHMARK_MAIN();
