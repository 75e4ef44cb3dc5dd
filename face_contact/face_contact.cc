#include "face_contact/face_contact.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <Eigen/SVD>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace visco::face_contact {
namespace {

using Eigen::Matrix3d;
using Eigen::Matrix4d;
using Eigen::MatrixXd;
using Eigen::Vector4d;
using Eigen::VectorXd;

Matrix4d RotX(double a) {
  Matrix4d m = Matrix4d::Identity();
  m(1, 1) = std::cos(a);
  m(1, 2) = -std::sin(a);
  m(2, 1) = std::sin(a);
  m(2, 2) = std::cos(a);
  return m;
}
Matrix4d RotY(double b) {
  Matrix4d m = Matrix4d::Identity();
  m(0, 0) = std::cos(b);
  m(0, 2) = std::sin(b);
  m(2, 0) = -std::sin(b);
  m(2, 2) = std::cos(b);
  return m;
}
Matrix4d RotZ(double c) {
  Matrix4d m = Matrix4d::Identity();
  m(0, 0) = std::cos(c);
  m(0, 1) = -std::sin(c);
  m(1, 0) = std::sin(c);
  m(1, 1) = std::cos(c);
  return m;
}
// Derivatives of the rotation matrices (zero fourth row and column).
Matrix4d DRotX(double a) {
  Matrix4d m = Matrix4d::Zero();
  m(1, 1) = -std::sin(a);
  m(1, 2) = -std::cos(a);
  m(2, 1) = std::cos(a);
  m(2, 2) = -std::sin(a);
  return m;
}
Matrix4d DRotY(double b) {
  Matrix4d m = Matrix4d::Zero();
  m(0, 0) = -std::sin(b);
  m(0, 2) = std::cos(b);
  m(2, 0) = -std::cos(b);
  m(2, 2) = -std::sin(b);
  return m;
}
Matrix4d DRotZ(double c) {
  Matrix4d m = Matrix4d::Zero();
  m(0, 0) = -std::sin(c);
  m(0, 1) = -std::cos(c);
  m(1, 0) = std::cos(c);
  m(1, 1) = -std::sin(c);
  return m;
}
Matrix4d Translation(double x, double y, double z) {
  Matrix4d m = Matrix4d::Identity();
  m(0, 3) = x;
  m(1, 3) = y;
  m(2, 3) = z;
  return m;
}

// Current values of the parameters and their derivatives with respect to the variable parts.
struct Evaluation {
  std::vector<Matrix4d> forward;                   // T_k·ΔT_k
  std::vector<Matrix4d> inverse;                   // ΔT_k⁻¹·T_k⁻¹
  std::vector<int> column;                         // first column of param k in q, or −1 when constant
  std::vector<std::array<Matrix4d, 6>> d_forward;  // per variable: T_k·∂ΔT/∂q_j
  std::vector<std::array<Matrix4d, 6>> d_inverse;  // per variable: ∂(ΔT⁻¹)/∂q_j·T_k⁻¹
};

Evaluation Evaluate(const ContactProblem& problem, const VectorXd& q, bool derivatives) {
  const int n_params = static_cast<int>(problem.params.size());
  if (q.size() != 6 * static_cast<Eigen::Index>(problem.variables.size())) {
    throw std::invalid_argument("face contact: q has " + std::to_string(q.size()) + " entries, expected 6 x " +
                                std::to_string(problem.variables.size()) + " variables");
  }
  Evaluation ev;
  ev.forward = problem.params;
  ev.inverse.resize(n_params);
  ev.column.assign(n_params, -1);
  for (size_t v = 0; v < problem.variables.size(); ++v) {
    const int k = problem.variables[v];
    if (k < 0 || k >= n_params) throw std::invalid_argument("face contact: variable index out of range");
    if (ev.column[k] >= 0) throw std::invalid_argument("face contact: a parameter is listed twice as variable");
    ev.column[k] = static_cast<int>(6 * v);
  }
  if (derivatives) {
    ev.d_forward.resize(problem.variables.size());
    ev.d_inverse.resize(problem.variables.size());
  }
  for (int k = 0; k < n_params; ++k) {
    if (ev.column[k] < 0) {
      ev.inverse[k] = RigidInverse(problem.params[k]);
      continue;
    }
    const Vector6d qk = q.segment<6>(ev.column[k]);
    const Matrix4d delta = DeltaTransform(qk);
    const Matrix4d delta_inv = RigidInverse(delta);
    const Matrix4d t_inv = RigidInverse(problem.params[k]);
    ev.forward[k] = problem.params[k] * delta;
    ev.inverse[k] = delta_inv * t_inv;
    if (derivatives) {
      const int v = ev.column[k] / 6;
      for (int j = 0; j < 6; ++j) {
        const Matrix4d d = DeltaTransformDerivative(qk, j);
        ev.d_forward[v][j] = problem.params[k] * d;
        ev.d_inverse[v][j] = -delta_inv * d * delta_inv * t_inv;
      }
    }
  }
  return ev;
}

void CheckGroup(const ContactProblem& problem, const ContactGroup& group) {
  for (const OdlFactor& f : group.chain) {
    if (f.param < 0 || f.param >= static_cast<int>(problem.params.size())) {
      throw std::invalid_argument("face contact: chain refers to parameter " + std::to_string(f.param) + " of " +
                                  std::to_string(problem.params.size()));
    }
  }
}

// Thin SVD J = U·diag(s)·Vᵀ, singular values descending. BDCSVD (divide and conquer) is fast on the large systems,
// but Eigen 3.4.0's BDCSVD returned a wrong decomposition for some of our Jacobians (several exactly zero columns;
// seen on a 20×24 one: singular values and vectors off, U and V still orthonormal). So its output is checked
// (J·V = U·diag(s), VᵀV = I) and JacobiSVD (one-sided Jacobi, slower, robust) used when the check fails.
struct Svd {
  MatrixXd u;
  VectorXd s;
  MatrixXd v;
};

Svd ThinSvd(const MatrixXd& j) {
  Svd out;
  Eigen::BDCSVD<MatrixXd> bdc(j, Eigen::ComputeThinU | Eigen::ComputeThinV);
  const MatrixXd& u = bdc.matrixU();
  const MatrixXd& v = bdc.matrixV();
  const VectorXd& s = bdc.singularValues();
  const double scale = std::max(1.0, s.size() > 0 ? s[0] : 0.0);
  const bool good =
      s.size() == 0 || ((j * v - u * s.asDiagonal()).cwiseAbs().maxCoeff() <= 1e-11 * scale &&
                        (v.transpose() * v - MatrixXd::Identity(v.cols(), v.cols())).cwiseAbs().maxCoeff() <= 1e-11);
  if (good) {
    out.u = u;
    out.s = s;
    out.v = v;
    return out;
  }
  Eigen::JacobiSVD<MatrixXd> jacobi(j, Eigen::ComputeThinU | Eigen::ComputeThinV);
  out.u = jacobi.matrixU();
  out.s = jacobi.singularValues();
  out.v = jacobi.matrixV();
  return out;
}

double MaxAbs(const VectorXd& v) { return v.size() == 0 ? 0.0 : v.cwiseAbs().maxCoeff(); }

// Column weights: translation columns 1, rotation columns 1/L (J_p = J_q·W⁻¹ with p = W·q).
VectorXd InverseWeights(int unknowns, double characteristic_length) {
  VectorXd w(unknowns);
  for (int i = 0; i < unknowns; ++i) w[i] = (i % 6) < 3 ? 1.0 : 1.0 / characteristic_length;
  return w;
}

}  // namespace

Matrix4d DeltaTransform(const Vector6d& q) {
  return Translation(q[0], q[1], q[2]) * RotX(q[3]) * RotY(q[4]) * RotZ(q[5]);
}

Matrix4d DeltaTransformDerivative(const Vector6d& q, int j) {
  Matrix4d m = Matrix4d::Zero();
  switch (j) {
    case 0:
    case 1:
    case 2:
      // ∂P/∂x·R = E_{x,w}·R = E_{x,w}: R's last row is (0, 0, 0, 1). Eqs. 27–29 hold at every q.
      m(j, 3) = 1.0;
      return m;
    case 3:
      return Translation(q[0], q[1], q[2]) * DRotX(q[3]) * RotY(q[4]) * RotZ(q[5]);
    case 4:
      return Translation(q[0], q[1], q[2]) * RotX(q[3]) * DRotY(q[4]) * RotZ(q[5]);
    case 5:
      return Translation(q[0], q[1], q[2]) * RotX(q[3]) * RotY(q[4]) * DRotZ(q[5]);
    default:
      throw std::invalid_argument("DeltaTransformDerivative: j must be 0..5");
  }
}

Vector6d DeltaParameters(const Matrix4d& delta) {
  Vector6d q;
  q.head<3>() = delta.block<3, 1>(0, 3);
  // R = Rx(α)·Ry(β)·Rz(γ): R02 = sin β, R12 = −sin α cos β, R22 = cos α cos β, R01 = −cos β sin γ, R00 = cos β cos γ.
  const double sb = std::clamp(delta(0, 2), -1.0, 1.0);
  q[4] = std::asin(sb);
  q[3] = std::atan2(-delta(1, 2), delta(2, 2));
  q[5] = std::atan2(-delta(0, 1), delta(0, 0));
  return q;
}

Matrix4d RigidInverse(const Matrix4d& t) {
  Matrix4d inv = Matrix4d::Identity();
  const Matrix3d rt = t.block<3, 3>(0, 0).transpose();
  inv.block<3, 3>(0, 0) = rt;
  inv.block<3, 1>(0, 3) = -rt * t.block<3, 1>(0, 3);
  return inv;
}

Odl InverseOdl(const Odl& odl) {
  Odl out;
  out.reserve(odl.size());
  for (auto it = odl.rbegin(); it != odl.rend(); ++it) out.push_back({it->param, !it->inverse});
  return out;
}

Odl ConcatenateOdl(const Odl& a, const Odl& b) {
  Odl out = a;
  for (const OdlFactor& f : b) {
    if (!out.empty() && out.back().param == f.param && out.back().inverse != f.inverse) {
      out.pop_back();
    } else {
      out.push_back(f);
    }
  }
  return out;
}

int EquationCount(const ContactProblem& problem) {
  int n = 0;
  for (const ContactGroup& g : problem.groups) n += static_cast<int>(g.points.size());
  return n;
}

std::vector<Matrix4d> CorrectedParams(const ContactProblem& problem, const VectorXd& q) {
  return Evaluate(problem, q, false).forward;
}

VectorXd Residues(const ContactProblem& problem, const VectorXd& q) {
  const Evaluation ev = Evaluate(problem, q, false);
  VectorXd e(EquationCount(problem));
  int row = 0;
  for (const ContactGroup& g : problem.groups) {
    CheckGroup(problem, g);
    Eigen::RowVector4d left = g.plane.transpose();
    for (const OdlFactor& f : g.chain) left = left * (f.inverse ? ev.inverse[f.param] : ev.forward[f.param]);
    for (const Eigen::Vector3d& v : g.points) e[row++] = left.head<3>().dot(v) + left[3];
  }
  return e;
}

MatrixXd Jacobian(const ContactProblem& problem, const VectorXd& q) {
  const Evaluation ev = Evaluate(problem, q, true);
  const int unknowns = static_cast<int>(6 * problem.variables.size());
  MatrixXd jac = MatrixXd::Zero(EquationCount(problem), unknowns);
  int row = 0;
  std::vector<Eigen::RowVector4d> left;
  std::vector<Matrix4d> suffix;
  for (const ContactGroup& g : problem.groups) {
    CheckGroup(problem, g);
    const size_t len = g.chain.size();
    // left[i] = nᵀ·F_0···F_(i−1); suffix[i] = F_(i+1)···F_(len−1).
    left.assign(len + 1, g.plane.transpose());
    for (size_t i = 0; i < len; ++i) {
      const OdlFactor& f = g.chain[i];
      left[i + 1] = left[i] * (f.inverse ? ev.inverse[f.param] : ev.forward[f.param]);
    }
    suffix.assign(len, Matrix4d::Identity());
    for (size_t i = len; i-- > 1;) {
      const OdlFactor& f = g.chain[i];
      suffix[i - 1] = (f.inverse ? ev.inverse[f.param] : ev.forward[f.param]) * suffix[i];
    }
    for (size_t i = 0; i < len; ++i) {
      const OdlFactor& f = g.chain[i];
      const int col = ev.column[f.param];
      if (col < 0) continue;
      const auto& d = f.inverse ? ev.d_inverse[col / 6] : ev.d_forward[col / 6];
      Eigen::Matrix<double, 6, 4> rows;
      for (int j = 0; j < 6; ++j) rows.row(j) = left[i] * d[j] * suffix[i];
      for (size_t p = 0; p < g.points.size(); ++p) {
        const Vector4d v(g.points[p].x(), g.points[p].y(), g.points[p].z(), 1.0);
        jac.block<1, 6>(row + static_cast<int>(p), col) += (rows * v).transpose();
      }
    }
    row += static_cast<int>(g.points.size());
  }
  return jac;
}

const char* ToString(SolveStatus status) {
  switch (status) {
    case SolveStatus::kConverged:
      return "converged";
    case SolveStatus::kInconsistent:
      return "inconsistent";
    case SolveStatus::kNotConverged:
      return "not converged";
  }
  return "?";
}

SolveReport SolveContacts(const ContactProblem& problem, const SolverOptions& options) {
  if (!(options.characteristic_length > 0)) throw std::invalid_argument("characteristic length must be > 0");
  if (!(options.residue_tolerance > 0)) throw std::invalid_argument("residue tolerance must be > 0");
  SolveReport report;
  const int unknowns = static_cast<int>(6 * problem.variables.size());
  report.unknowns = unknowns;
  report.equations = EquationCount(problem);
  report.q = VectorXd::Zero(unknowns);
  const VectorXd inv_w = InverseWeights(unknowns, options.characteristic_length);
  // Everything below works in the weighted coordinates p = W·q, so that the Euclidean norm is the metric.
  auto residues_p = [&](const VectorXd& p) -> VectorXd { return Residues(problem, p.cwiseProduct(inv_w)); };
  auto jacobian_p = [&](const VectorXd& p) -> MatrixXd {
    return Jacobian(problem, p.cwiseProduct(inv_w)) * inv_w.asDiagonal();
  };
  auto worst = [&](const VectorXd& e) {
    int row = 0, best = -1;
    double best_value = -1;
    for (size_t g = 0; g < problem.groups.size(); ++g) {
      for (size_t i = 0; i < problem.groups[g].points.size(); ++i, ++row) {
        if (std::abs(e[row]) > best_value) {
          best_value = std::abs(e[row]);
          best = static_cast<int>(g);
        }
      }
    }
    return best;
  };
  auto finish = [&](const VectorXd& p, SolveStatus status, std::string message) {
    report.q = p.cwiseProduct(inv_w);
    report.corrected = CorrectedParams(problem, report.q);
    const VectorXd e = Residues(problem, report.q);
    report.max_residue = MaxAbs(e);
    report.worst_group = worst(e);
    report.correction_norm = p.norm();
    report.status = status;
    report.message = std::move(message);
    return report;
  };

  VectorXd p = VectorXd::Zero(unknowns);
  VectorXd e = residues_p(p);
  report.observed_max_residue = MaxAbs(e);
  const double tol = options.residue_tolerance;
  if (unknowns == 0 || report.equations == 0) {
    report.rank_gap = std::numeric_limits<double>::infinity();
    if (MaxAbs(e) <= tol) return finish(p, SolveStatus::kConverged, "every contact already holds");
    return finish(p, SolveStatus::kInconsistent, "contacts do not hold and no motion parameter is variable");
  }

  // Phase 1: Levenberg–Marquardt to any configuration where every contact holds (polished well below tol so that
  // the redundant singular values there are at rounding level).
  const double polish = std::min(tol, 1e-12);
  double lambda = 1e-6;
  int slow_steps = 0;
  bool solved = false;
  Svd svd;
  for (report.search_iterations = 0; report.search_iterations < options.max_iterations; ++report.search_iterations) {
    if (MaxAbs(e) <= polish) {
      solved = true;
      break;
    }
    svd = ThinSvd(jacobian_p(p));
    const VectorXd& s = svd.s;
    if (s.size() == 0 || s[0] == 0) break;
    const VectorXd g = svd.u.transpose() * e;
    bool accepted = false;
    while (!accepted && lambda < 1e12) {
      const double mu = lambda * s[0] * s[0];
      VectorXd scaled(s.size());
      for (Eigen::Index i = 0; i < s.size(); ++i) scaled[i] = s[i] / (s[i] * s[i] + mu) * g[i];
      const VectorXd trial = p - svd.v * scaled;
      const VectorXd e_trial = residues_p(trial);
      if (e_trial.norm() < e.norm()) {
        slow_steps = (e.norm() - e_trial.norm() < 1e-6 * e.norm()) ? slow_steps + 1 : 0;
        p = trial;
        e = e_trial;
        lambda = std::max(lambda / 10, 1e-15);
        accepted = true;
      } else {
        lambda *= 10;
      }
    }
    if (!accepted || slow_steps >= 5) break;  // stalled at a least-squares point
  }
  if (!solved && MaxAbs(e) > tol) {
    const VectorXd p_ls = p;
    finish(p_ls, SolveStatus::kInconsistent, "");
    report.message =
        fmt::format("the contacts cannot all hold: least squares stalls at max residue {:.3g} m after {} iterations",
                    report.max_residue, report.search_iterations);
    if (report.search_iterations >= options.max_iterations) {
      report.status = SolveStatus::kNotConverged;
      report.message = fmt::format("no configuration found within {} iterations (max residue {:.3g} m)",
                                   options.max_iterations, report.max_residue);
    }
    return report;
  }
  const VectorXd p_any = p;
  svd = ThinSvd(jacobian_p(p_any));
  {
    const VectorXd& s = svd.s;
    int r = 0;
    while (r < s.size() && s[r] > options.rank_tolerance * s[0]) ++r;
    report.rank = r;
  }
  const int rank = report.rank;

  // Phase 2: Newton–Raphson with the SVD truncated to the structural rank, from the observation (and, should that
  // fail, from the phase-1 solution). q ← V_r W_r⁻¹ U_rᵀ (J·q − e): the paper's step without the null-space drift.
  auto newton = [&](VectorXd start, int& iterations) {
    VectorXd x = std::move(start);
    double step = std::numeric_limits<double>::infinity();
    for (iterations = 0; iterations < options.max_iterations; ++iterations) {
      const VectorXd ex = residues_p(x);
      if (MaxAbs(ex) <= tol && step <= 1e-12 * std::max(1.0, x.norm())) return std::make_pair(x, true);
      const MatrixXd jx = jacobian_p(x);
      svd = ThinSvd(jx);
      const int r = std::min<int>(rank, static_cast<int>(svd.s.size()));
      const VectorXd rhs = jx * x - ex;
      const VectorXd coeff = (svd.u.leftCols(r).transpose() * rhs).cwiseQuotient(svd.s.head(r));
      const VectorXd next = svd.v.leftCols(r) * coeff;
      step = (next - x).norm();
      x = next;
      if (!x.allFinite()) break;
    }
    return std::make_pair(x, false);
  };
  int iterations = 0;
  auto [p_min, ok] = newton(VectorXd::Zero(unknowns), iterations);
  report.newton_iterations = iterations;
  std::string how = "from the observation";
  if (!ok) {
    auto [p_retry, ok_retry] = newton(p_any, iterations);
    report.newton_iterations += iterations;
    if (ok_retry) {
      p_min = p_retry;
      ok = true;
      how = "from the phase-1 solution";
    }
  }
  if (!ok) {
    finish(p_any, SolveStatus::kNotConverged, "");
    report.message = "the contacts can hold, but Newton–Raphson for the smallest correction did not converge within " +
                     std::to_string(options.max_iterations) + " iterations";
    return report;
  }
  // Certificate: the correction has no component in the null space of J at the solution, and the rank is
  // structural (a clear gap after the kept singular values).
  svd = ThinSvd(jacobian_p(p_min));
  const VectorXd& s = svd.s;
  const MatrixXd vr = svd.v.leftCols(rank);
  report.null_space_component = (p_min - vr * (vr.transpose() * p_min)).norm();
  if (rank > 0 && rank < unknowns) {
    const double next = rank < s.size() ? s[rank] : 0.0;
    report.rank_gap = next > 0 ? s[rank - 1] / next : std::numeric_limits<double>::infinity();
  } else {
    report.rank_gap = std::numeric_limits<double>::infinity();
  }
  finish(p_min, SolveStatus::kConverged, "");
  report.message = fmt::format(
      "every contact holds (max residue {:.2g} m) after {} + {} iterations ({}); rank {} of {} unknowns, the other {} "
      "keep their observed values",
      report.max_residue, report.search_iterations, report.newton_iterations, how, rank, unknowns, unknowns - rank);
  return report;
}

}  // namespace visco::face_contact
