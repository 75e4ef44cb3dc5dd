#include "vision/contact_refinement.h"

#include <Eigen/Cholesky>
#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "face_contact/flush_poses.h"

namespace visco::vision {
namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;

// One face contact as equations on the poses: face `fa` of object a (outward unit normal n_a through p_a, a's frame)
// against face `fb` of object b (normal n_b). c = [t1.(N_a + N_b), t2.(N_a + N_b), N_a.(T_b q_b - T_a p_a)] (world
// normals N = R n; t1, t2 span a's face plane at the flush poses; q_b the point of b's face plane that was under p_a
// there): the normals opposite and the planes coincident. Near the solution their gradients span the same space as
// MakeFlush's vertex-to-plane equations of the contact region (any other point of b's face adds a combination of
// the two normal equations), so the constraint manifold, and Sigma', are the same.
struct ContactEquations {
  int a = -1, b = -1;
  Eigen::Vector3d n_a, p_a, n_b, q_b, t1, t2;
  std::vector<Eigen::Vector3d> face_a;  // a's face vertices (for the residue)
};

void FacePlane(const face_contact::Polyhedron& p, int f, Eigen::Vector3d& normal, Eigen::Vector3d& centroid) {
  const auto& face = p.faces[static_cast<std::size_t>(f)];
  normal.setZero();
  centroid.setZero();
  for (std::size_t i = 0; i < face.size(); ++i) {
    const Eigen::Vector3d& u = p.vertices[static_cast<std::size_t>(face[i])];
    const Eigen::Vector3d& w = p.vertices[static_cast<std::size_t>(face[(i + 1) % face.size()])];
    normal += u.cross(w);  // Newell
    centroid += u / static_cast<double>(face.size());
  }
  normal.normalize();
}

Eigen::Vector3d Residual(const ContactEquations& c, const std::vector<Eigen::Isometry3d>& poses) {
  const Eigen::Isometry3d& ta = poses[static_cast<std::size_t>(c.a)];
  const Eigen::Isometry3d& tb = poses[static_cast<std::size_t>(c.b)];
  const Eigen::Vector3d na = ta.linear() * c.n_a, sum = na + tb.linear() * c.n_b;
  return {c.t1.dot(sum), c.t2.dot(sum), na.dot(tb * c.q_b - ta * c.p_a)};
}

// Largest distance of a's face vertices to b's face plane.
double Residue(const ContactEquations& c, const std::vector<Eigen::Isometry3d>& poses) {
  const Eigen::Isometry3d& ta = poses[static_cast<std::size_t>(c.a)];
  const Eigen::Isometry3d& tb = poses[static_cast<std::size_t>(c.b)];
  const Eigen::Vector3d nb = tb.linear() * c.n_b, qb = tb * c.q_b;
  double worst = 0;
  for (const auto& v : c.face_a) worst = std::max(worst, std::abs(nb.dot(ta * v - qb)));
  return worst;
}

// The object's pose covariance in face_contact's parametrisation (wMo·ΔT(q), q = (p, φ) in the object frame): to first
// order Exp(w)·R = R·Exp(Rᵀw) and t + v = t + R·(Rᵀv), so q = [Rᵀv, Rᵀw] (and Rx·Ry·Rz of small angles is the
// rotation vector). Without a covariance: isotropic from the stddevs.
face_contact::PoseCovariance PlanningCovariance(const ContactObject& o) {
  PoseCovariance c = o.covariance;
  if (!(c.trace() > 0)) {
    c.setZero();
    c.diagonal() << Eigen::Vector3d::Constant(o.orientation_stddev * o.orientation_stddev),
        Eigen::Vector3d::Constant(o.position_stddev * o.position_stddev);
  }
  Eigen::Matrix<double, 6, 6> g = Eigen::Matrix<double, 6, 6>::Zero();
  g.block<3, 3>(0, 3) = o.wMo.linear().transpose();  // p from v
  g.block<3, 3>(3, 0) = o.wMo.linear().transpose();  // φ from w
  return g * c * g.transpose();
}

}  // namespace

PrismMesh ObjectPrism(const ObjectModel& model) {
  // face_contact::MakePrism extrudes a profile (x, z) along y; turned by Rx(-90 deg) ((x, y, z) -> (x, z, -y), a proper
  // rotation: faces stay outward) and lifted by height / 2, it is the vertical prism over the polygon.
  std::vector<Eigen::Vector2d> profile = model.polygon;
  double area2 = 0;
  for (std::size_t i = 0; i < profile.size(); ++i) {
    const auto& a = profile[i];
    const auto& b = profile[(i + 1) % profile.size()];
    area2 += a.x() * b.y() - a.y() * b.x();
  }
  if (area2 < 0) std::reverse(profile.begin(), profile.end());  // MakePrism wants counter-clockwise
  const face_contact::Polyhedron p = face_contact::MakePrism(profile, model.height);
  PrismMesh mesh;
  for (const auto& v : p.vertices) mesh.vertices.emplace_back(v.x(), v.z(), -v.y() + model.height / 2);
  mesh.faces = p.faces;
  return mesh;
}

ContactRefinement RefineContacts(const std::vector<ContactObject>& objects, const ContactOptions& options) {
  ContactRefinement out;
  for (const auto& o : objects) out.wMo.push_back(o.wMo), out.covariance.push_back(o.covariance);
  out.joint_covariance = Eigen::MatrixXd::Zero(6 * static_cast<Eigen::Index>(objects.size()),
                                               6 * static_cast<Eigen::Index>(objects.size()));
  for (std::size_t i = 0; i < objects.size(); ++i) {
    out.joint_covariance.block<6, 6>(6 * static_cast<Eigen::Index>(i), 6 * static_cast<Eigen::Index>(i)) =
        objects[i].covariance;
  }
  out.in_contact.assign(objects.size(), false);
  if (!options.enabled || objects.empty()) {
    out.message = "contact refinement off";
    return out;
  }
  std::vector<face_contact::FlushObject> flush;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e18), hi = Eigen::Vector2d::Constant(-1e18);
  for (const auto& o : objects) {
    const PrismMesh mesh = ObjectPrism(*o.model);
    face_contact::FlushObject f;
    f.id = o.model->id;
    f.model.vertices = mesh.vertices;
    f.model.faces = mesh.faces;
    f.pose = o.wMo;
    f.covariance = PlanningCovariance(o);
    flush.push_back(std::move(f));
    for (const auto& v : mesh.vertices) {
      const Eigen::Vector2d w = (o.wMo * v).head<2>();
      lo = lo.cwiseMin(w), hi = hi.cwiseMax(w);
    }
  }
  // The table: a stable box under everything in view, its top face the plane z = 0.
  face_contact::FlushObject table;
  table.id = "table";
  table.stable = true;
  const Eigen::Vector2d size = (hi - lo).array() + 1.0;
  table.model = face_contact::MakeBox(Eigen::Vector3d(size.x(), size.y(), options.table_thickness_m));
  table.pose.translation() << (lo + hi) / 2, -options.table_thickness_m;
  if (options.table_covariance.trace() > 0) {
    // About the world origin -> PerturbPose at the table's pose (t' = t + w x t + v), then face_contact's convention.
    Eigen::Matrix<double, 6, 6> a = Eigen::Matrix<double, 6, 6>::Identity();
    a.block<3, 3>(3, 0) = -Skew(table.pose.translation());
    ContactObject as_object;
    as_object.wMo = table.pose;
    as_object.covariance = a * options.table_covariance * a.transpose();
    table.covariance = PlanningCovariance(as_object);
  }
  flush.push_back(table);

  face_contact::FlushOptions fo;
  fo.contact.false_miss_probability = options.false_miss_probability;
  fo.contact.min_distance = options.min_distance_m;
  fo.contact.min_angle_deg = options.min_angle_deg;
  face_contact::FlushResult r;
  try {
    r = face_contact::MakeFlush(flush, fo);
  } catch (const std::invalid_argument& e) {
    out.message = e.what();
    return out;
  }
  out.contacts = static_cast<int>(r.contacts.size());
  out.observed_gap_m = r.report.observed_max_residue;
  out.max_residue_m = r.report.max_residue;
  out.message = r.message;
  if (!r.ok || r.contacts.empty()) return out;
  out.ok = true;
  for (const auto& c : r.contacts) {
    if (c.object < static_cast<int>(objects.size())) out.in_contact[static_cast<std::size_t>(c.object)] = true;
    if (c.against < static_cast<int>(objects.size())) out.in_contact[static_cast<std::size_t>(c.against)] = true;
  }
  for (std::size_t i = 0; i < objects.size(); ++i) out.wMo[i] = r.poses[i];

  // The covariance-weighted projection and the propagated covariance (see the header).
  const int n = static_cast<int>(objects.size());
  std::vector<int> var(flush.size(), -1);  // object -> variable block
  int nv = 0;
  bool have_cov = true;
  for (int i = 0; i < n; ++i) {
    if (!out.in_contact[static_cast<std::size_t>(i)]) continue;
    var[static_cast<std::size_t>(i)] = nv++;
    have_cov = have_cov && objects[static_cast<std::size_t>(i)].covariance.trace() > 0;
  }
  if (!have_cov || nv == 0) {
    out.message += "; no covariance: MakeFlush's poses, covariance not propagated";
    return out;
  }
  std::vector<ContactEquations> eqs;
  for (const auto& c : r.contacts) {
    ContactEquations e;
    e.a = c.object, e.b = c.against;
    const face_contact::Polyhedron& ma = flush[static_cast<std::size_t>(c.object)].model;
    const face_contact::Polyhedron& mb = flush[static_cast<std::size_t>(c.against)].model;
    Eigen::Vector3d cb;
    FacePlane(ma, c.face, e.n_a, e.p_a);
    FacePlane(mb, c.against_face, e.n_b, cb);
    for (int v : ma.faces[static_cast<std::size_t>(c.face)])
      e.face_a.push_back(ma.vertices[static_cast<std::size_t>(v)]);
    const Eigen::Isometry3d& ta = r.poses[static_cast<std::size_t>(c.object)];
    const Eigen::Isometry3d& tb = r.poses[static_cast<std::size_t>(c.against)];
    const Eigen::Vector3d x = tb.inverse() * (ta * e.p_a);
    e.q_b = x - e.n_b * e.n_b.dot(x - cb);
    const Eigen::Vector3d na = ta.linear() * e.n_a;
    e.t1 = na.unitOrthogonal();
    e.t2 = na.cross(e.t1);
    eqs.push_back(std::move(e));
  }
  const int m = 3 * static_cast<int>(eqs.size());
  Eigen::MatrixXd sigma = Eigen::MatrixXd::Zero(6 * nv, 6 * nv);
  for (int i = 0; i < n; ++i) {
    const int k = var[static_cast<std::size_t>(i)];
    if (k >= 0) sigma.block<6, 6>(6 * k, 6 * k) = objects[static_cast<std::size_t>(i)].covariance;
  }
  // Poses at the perturbation d (6 per variable) of `from` (the table and objects not in contact fixed).
  std::vector<Eigen::Isometry3d> measured(flush.size());
  for (std::size_t i = 0; i < flush.size(); ++i) measured[i] = i < objects.size() ? objects[i].wMo : flush[i].pose;
  auto poses_at = [&](const std::vector<Eigen::Isometry3d>& from, const Eigen::VectorXd& d) {
    std::vector<Eigen::Isometry3d> p = from;
    for (std::size_t i = 0; i < flush.size(); ++i) {
      if (var[i] >= 0) p[i] = PerturbPose(from[i], d.segment<6>(6 * var[i]));
    }
    return p;
  };
  auto residuals = [&](const std::vector<Eigen::Isometry3d>& from, const Eigen::VectorXd& d) {
    const auto p = poses_at(from, d);
    Eigen::VectorXd c(m);
    for (std::size_t k = 0; k < eqs.size(); ++k) c.segment<3>(3 * static_cast<Eigen::Index>(k)) = Residual(eqs[k], p);
    return c;
  };
  // Central differences: the equations are smooth (products of rotations and positions of size ~1), so the
  // truncation error is ~h^2 and the rounding error ~1e-16 / h: about 1e-10 relative for these steps.
  auto jacobian = [&](const std::vector<Eigen::Isometry3d>& from, const Eigen::VectorXd& d) {
    Eigen::MatrixXd j(m, 6 * nv);
    for (int k = 0; k < 6 * nv; ++k) {
      const double h = k % 6 < 3 ? 1e-6 : 1e-7;
      Eigen::VectorXd dp = d, dm = d;
      dp[k] += h, dm[k] -= h;
      j.col(k) = (residuals(from, dp) - residuals(from, dm)) / (2 * h);
    }
    return j;
  };
  // Contacts can be redundant (two objects side by side on the table: their tilt is fixed by the table and again
  // by their common face). On the manifold (MakeFlush's poses) the redundant combinations vanish exactly; away from
  // it they do not, and would make the steps ill-conditioned. So the equations are reduced to an orthonormal basis
  // U of the range of J there (SVD of J Sigma^1/2, singular values below 1e-8 of the largest dropped): c~ = U^T c,
  // full rank near the manifold and with the same zero set.
  const Eigen::LLT<Eigen::MatrixXd> llt(sigma);
  if (llt.info() != Eigen::Success) {
    out.message += "; a covariance is not positive definite: MakeFlush's poses, covariance not propagated";
    return out;
  }
  const Eigen::MatrixXd sigma_half = llt.matrixL();
  const Eigen::JacobiSVD<Eigen::MatrixXd> svd(jacobian(r.poses, Eigen::VectorXd::Zero(6 * nv)) * sigma_half,
                                              Eigen::ComputeFullU);
  int rank = 0;
  for (Eigen::Index i = 0; i < svd.singularValues().size(); ++i) {
    rank += svd.singularValues()[i] > 1e-8 * svd.singularValues()[0] ? 1 : 0;
  }
  const Eigen::MatrixXd basis = svd.matrixU().leftCols(rank).transpose();
  // Gauss-Newton for min d^T Sigma^-1 d subject to c~(d) = 0: each step solves the linearised constraints exactly,
  // d = Sigma J^T (J Sigma J^T)^-1 (J d - c~(d)).
  Eigen::VectorXd d = Eigen::VectorXd::Zero(6 * nv);
  for (int it = 0; it < 30; ++it) {
    const Eigen::MatrixXd j = basis * jacobian(measured, d);
    const Eigen::MatrixXd sjt = sigma * j.transpose();
    const Eigen::VectorXd next = sjt * (j * sjt).ldlt().solve(j * d - basis * residuals(measured, d));
    const double step = (next - d).cwiseAbs().maxCoeff();
    d = next;
    if (!(step > 1e-14)) break;
  }
  const std::vector<Eigen::Isometry3d> refined = poses_at(measured, d);
  double residue = 0;
  for (const auto& e : eqs) residue = std::max(residue, Residue(e, refined));
  if (!(residue <= 1e-9)) {
    out.message +=
        "; the covariance-weighted projection did not converge: MakeFlush's poses, covariance not propagated";
    return out;
  }
  // Sigma' at the solution (d is the perturbation of the measured poses, the parametrisation of Sigma).
  // The reduced equations have the same gradients' span there, without the redundant (exactly zero) directions.
  const Eigen::MatrixXd j = basis * jacobian(measured, d);
  const Eigen::MatrixXd sjt = sigma * j.transpose();
  Eigen::MatrixXd post = sigma - sjt * (j * sjt).ldlt().solve(sjt.transpose());
  post = (post + post.transpose()) / 2;
  for (int i = 0; i < n; ++i) {
    const int k = var[static_cast<std::size_t>(i)];
    if (k < 0) continue;
    out.wMo[static_cast<std::size_t>(i)] = refined[static_cast<std::size_t>(i)];
    out.covariance[static_cast<std::size_t>(i)] = post.block<6, 6>(6 * k, 6 * k);
    for (int other = 0; other < n; ++other) {
      const int l = var[static_cast<std::size_t>(other)];
      if (l >= 0) out.joint_covariance.block<6, 6>(6 * i, 6 * other) = post.block<6, 6>(6 * k, 6 * l);
    }
  }
  out.max_residue_m = residue;
  out.covariance_propagated = true;
  return out;
}

Eigen::Isometry3d PerturbPose(const Eigen::Isometry3d& m, const Eigen::Matrix<double, 6, 1>& d) {
  Eigen::Isometry3d out = m;
  const double a = d.head<3>().norm();
  if (a > 0) out.linear() = Eigen::AngleAxisd(a, d.head<3>() / a).toRotationMatrix() * m.linear();
  out.translation() += d.tail<3>();
  return out;
}

}  // namespace visco::vision
