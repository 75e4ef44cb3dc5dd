#pragma once
// Face contact equations and their solution (Suehiro & Ikeuchi 1991, §2 and §7).
//
// A face contact equation says that a point v of the environment object lies on the plane n of a face of the
// manipulated object: e = n · D_a⁻¹ · D_b · v (eq. 25), where D_a and D_b are operation dependency lists (ODLs):
// products of motion parameters T_k and their inverses. Each motion parameter is split into the observed constant
// part T_k and the variable part ΔT_k = P(x,y,z)·Rx(α)·Ry(β)·Rz(γ) (eq. 4), so T_k becomes T_k·ΔT_k and its inverse
// ΔT_k⁻¹·T_k⁻¹ (eq. 3, read as e = n·ΔT_a⁻¹·T_a⁻¹·T_b·ΔT_b·v, docs/semantics.md).
//
// SolveContacts finds the *smallest* correction q (six parameters per variable motion parameter) that makes every
// equation hold: minimise Σ_k |t_k|² + L²·|r_k|² (t translation, r the three angles, L the characteristic length,
// 0.1 m by default) subject to f(q) = 0. The redundant degrees of freedom (directions the contacts do not constrain)
// therefore keep their observed values: at the solution the correction has no component in the null space of the
// Jacobian. This is the paper's Newton–Raphson with the SVD and small singular values zeroed (eq. 23); the number of
// singular values kept is the structural rank of the contacts, measured where the contacts hold (see SolveContacts).
//
// Units: metres and radians. Frames: every T_k maps its object's frame to the world (ViSP's wMo).

#include <Eigen/Core>
#include <string>
#include <vector>

namespace visco::face_contact {

using Vector6d = Eigen::Matrix<double, 6, 1>;

/// The paper's variable matrix ΔT = P(x,y,z)·Rx(α)·Ry(β)·Rz(γ) (eqs. 4–8), q = (x, y, z, α, β, γ) in metres and
/// radians. ΔT(0) is the identity.
Eigen::Matrix4d DeltaTransform(const Vector6d& q);

/// ∂ΔT/∂q_j at q (j = 0..5, in the order x, y, z, α, β, γ). At q = 0 these are eqs. 27–32 of §7.
Eigen::Matrix4d DeltaTransformDerivative(const Vector6d& q, int j);

/// The parameters q with DeltaTransform(q) = delta (delta rigid; β is taken in [−90°, 90°]).
Vector6d DeltaParameters(const Eigen::Matrix4d& delta);

/// Inverse of a rigid homogeneous transform.
Eigen::Matrix4d RigidInverse(const Eigen::Matrix4d& t);

/// One factor of an operation dependency list: motion parameter `param` (T·ΔT), or its inverse (ΔT⁻¹·T⁻¹).
struct OdlFactor {
  int param = 0;
  bool inverse = false;
  bool operator==(const OdlFactor& other) const = default;
};

/// An operation dependency list (§3.2.1): the product of its factors, left to right, is an object's configuration.
using Odl = std::vector<OdlFactor>;

/// D⁻¹ as a list: the factors reversed, each inverted.
Odl InverseOdl(const Odl& odl);

/// a·b as a list, with adjacent factors T·T⁻¹ cancelled (they cancel exactly, variable part included).
Odl ConcatenateOdl(const Odl& a, const Odl& b);

/// Face contact equations that share one chain and one plane: e_i = plane · Π chain · (points_i, 1).
struct ContactGroup {
  Odl chain;                            ///< D_a⁻¹·D_b: from the vertex owner's frame to the face owner's frame.
  Eigen::Vector4d plane;                ///< (n_x, n_y, n_z, −d), |n| = 1, in the face owner's frame.
  std::vector<Eigen::Vector3d> points;  ///< contact vertices in the vertex owner's frame, metres.
  int tag = -1;                         ///< caller's label (for example the relation), reported back.
};

/// The system f(q) = e: constant parts of the motion parameters, which of them are variable, and the equations.
struct ContactProblem {
  std::vector<Eigen::Matrix4d> params;  ///< observed T_k (object frame to world).
  std::vector<int> variables;           ///< indices into params that receive a ΔT; q has 6 entries per variable.
  std::vector<ContactGroup> groups;
};

/// Number of scalar equations (points over all groups).
int EquationCount(const ContactProblem& problem);

/// The configurations T_k·ΔT(q_k) for every parameter (constant ones unchanged).
std::vector<Eigen::Matrix4d> CorrectedParams(const ContactProblem& problem, const Eigen::VectorXd& q);

/// Residues e (metres), one per point, group by group. @throws std::invalid_argument on size mismatches.
Eigen::VectorXd Residues(const ContactProblem& problem, const Eigen::VectorXd& q);

/// Analytic Jacobian ∂e/∂q (§7, eqs. 27–32 at q = 0, their exact generalisation elsewhere), rows as Residues,
/// columns (x, y, z, α, β, γ) per variable in the order of problem.variables.
Eigen::MatrixXd Jacobian(const ContactProblem& problem, const Eigen::VectorXd& q);

/// Options of SolveContacts.
struct SolverOptions {
  double characteristic_length = 0.1;  ///< metres: a rotation of 1 rad weighs like a translation of this length.
  double residue_tolerance = 1e-10;    ///< metres: every |e| at most this at convergence.
  double rank_tolerance = 1e-7;        ///< singular values below this × the largest, at a solution, are zero.
  int max_iterations = 100;            ///< per phase.
};

enum class SolveStatus {
  kConverged,     ///< every contact holds; the correction is the smallest one (null-space component vanishes).
  kInconsistent,  ///< no configuration near the observation satisfies every contact (least squares stalls above).
  kNotConverged,  ///< the iteration limit was reached.
};

/// What SolveContacts found, in words and figures a user can read.
struct SolveReport {
  SolveStatus status = SolveStatus::kNotConverged;
  Eigen::VectorXd q;                       ///< the correction (6 per variable; metres, radians).
  std::vector<Eigen::Matrix4d> corrected;  ///< T_k·ΔT(q_k) for every parameter.
  double observed_max_residue = 0;         ///< max |e| at the observation, metres.
  double max_residue = 0;                  ///< max |e| at the returned configuration, metres.
  int worst_group = -1;                    ///< group with the largest |e| at the returned configuration.
  int equations = 0;
  int unknowns = 0;
  int rank = 0;                     ///< structural rank: singular values kept.
  double rank_gap = 0;              ///< σ_rank / σ_(rank+1) at the solution (infinite when nothing was dropped).
  double null_space_component = 0;  ///< weighted norm of the correction's component in the Jacobian's null space.
  double correction_norm = 0;       ///< weighted norm of q.
  int search_iterations = 0;        ///< phase 1 (Levenberg–Marquardt to any solution; gives the rank).
  int newton_iterations = 0;        ///< phase 2 (Newton–Raphson with SVD from the observation).
  std::string message;              ///< one sentence: what happened.
};

/// Solve the face contact equations for the smallest weighted correction.
///
/// Phase 1 (rank): Levenberg–Marquardt from the observation to any configuration where every contact holds; the
/// Jacobian there has exact zero singular values for the redundant directions, so its rank (relative threshold
/// rank_tolerance) is the structural rank r. At the noisy observation the same directions have small but non-zero
/// singular values, which is why the rank is not taken there. If phase 1 stalls above residue_tolerance the
/// contacts are inconsistent (status kInconsistent).
/// Phase 2 (correction): Newton–Raphson from the observation with the SVD truncated to r (eq. 23), in the form
/// q ← V_r W_r⁻¹ U_rᵀ (J q − e), which equals the paper's step Δq = −V W* Uᵀ e minus the null-space component of the
/// accumulated correction; at convergence q lies in the row space of J, i.e. it is the smallest correction.
/// Not real-time safe (allocates).
SolveReport SolveContacts(const ContactProblem& problem, const SolverOptions& options = {});

/// Text of a status ("converged", "inconsistent", "not converged").
const char* ToString(SolveStatus status);

}  // namespace visco::face_contact
