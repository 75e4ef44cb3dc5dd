#include "face_contact/polyhedron.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>

#include "face_contact/face_contact.h"

namespace visco::face_contact {
namespace {

using Eigen::Matrix4d;
using Eigen::Vector2d;
using Eigen::Vector3d;
using Polygon2 = std::vector<Vector2d>;

Vector3d NewellNormal(const Polyhedron& model, const std::vector<int>& face) {
  Vector3d n = Vector3d::Zero();
  for (size_t i = 0; i < face.size(); ++i) {
    const Vector3d& p = model.vertices[face[i]];
    const Vector3d& q = model.vertices[face[(i + 1) % face.size()]];
    n.x() += (p.y() - q.y()) * (p.z() + q.z());
    n.y() += (p.z() - q.z()) * (p.x() + q.x());
    n.z() += (p.x() - q.x()) * (p.y() + q.y());
  }
  return n;  // twice the vector area
}

double Cross(const Vector2d& o, const Vector2d& a, const Vector2d& b) {
  return (a.x() - o.x()) * (b.y() - o.y()) - (a.y() - o.y()) * (b.x() - o.x());
}

double SignedArea(const Polygon2& poly) {
  double area = 0;
  for (size_t i = 0; i < poly.size(); ++i) {
    const Vector2d& p = poly[i];
    const Vector2d& q = poly[(i + 1) % poly.size()];
    area += p.x() * q.y() - q.x() * p.y();
  }
  return area / 2;
}

// Ear-clipping triangulation of a counter-clockwise simple polygon.
std::vector<std::array<Vector2d, 3>> Triangulate(Polygon2 poly, double eps) {
  std::vector<std::array<Vector2d, 3>> triangles;
  // Drop repeated and collinear vertices.
  for (bool changed = true; changed && poly.size() > 3;) {
    changed = false;
    for (size_t i = 0; i < poly.size() && poly.size() > 3; ++i) {
      const Vector2d& prev = poly[(i + poly.size() - 1) % poly.size()];
      const Vector2d& next = poly[(i + 1) % poly.size()];
      if (std::abs(Cross(prev, poly[i], next)) <= eps * eps && (next - prev).dot(poly[i] - prev) >= 0) {
        poly.erase(poly.begin() + static_cast<long>(i));
        changed = true;
      }
    }
  }
  while (poly.size() > 3) {
    bool clipped = false;
    const size_t n = poly.size();
    for (size_t i = 0; i < n; ++i) {
      const Vector2d& a = poly[(i + n - 1) % n];
      const Vector2d& b = poly[i];
      const Vector2d& c = poly[(i + 1) % n];
      if (Cross(a, b, c) <= 0) continue;  // reflex or flat
      bool inside = false;
      for (size_t j = 0; j < n && !inside; ++j) {
        if (j == i || j == (i + n - 1) % n || j == (i + 1) % n) continue;
        const Vector2d& p = poly[j];
        inside = Cross(a, b, p) > 0 && Cross(b, c, p) > 0 && Cross(c, a, p) > 0;
      }
      if (inside) continue;
      triangles.push_back({a, b, c});
      poly.erase(poly.begin() + static_cast<long>(i));
      clipped = true;
      break;
    }
    if (!clipped) break;  // degenerate input: fall back to a fan of what is left
  }
  for (size_t i = 1; i + 1 < poly.size(); ++i) triangles.push_back({poly[0], poly[i], poly[i + 1]});
  return triangles;
}

// Sutherland–Hodgman: the part of `subject` inside the counter-clockwise convex polygon `clip`.
Polygon2 ClipConvex(Polygon2 subject, const Polygon2& clip) {
  for (size_t i = 0; i < clip.size() && !subject.empty(); ++i) {
    const Vector2d& a = clip[i];
    const Vector2d& b = clip[(i + 1) % clip.size()];
    Polygon2 out;
    for (size_t j = 0; j < subject.size(); ++j) {
      const Vector2d& p = subject[j];
      const Vector2d& q = subject[(j + 1) % subject.size()];
      const double dp = Cross(a, b, p);
      const double dq = Cross(a, b, q);
      if (dp >= 0) out.push_back(p);
      if ((dp >= 0) != (dq >= 0)) out.push_back(p + (q - p) * (dp / (dp - dq)));
    }
    subject = std::move(out);
  }
  return subject;
}

Polygon2 ConvexHull(Polygon2 points) {
  std::sort(points.begin(), points.end(),
            [](const Vector2d& a, const Vector2d& b) { return a.x() < b.x() || (a.x() == b.x() && a.y() < b.y()); });
  if (points.size() < 3) return points;
  Polygon2 hull(2 * points.size());
  size_t k = 0;
  for (const Vector2d& p : points) {
    while (k >= 2 && Cross(hull[k - 2], hull[k - 1], p) <= 0) --k;
    hull[k++] = p;
  }
  for (size_t i = points.size() - 1, t = k + 1; i-- > 0;) {
    while (k >= t && Cross(hull[k - 2], hull[k - 1], points[i]) <= 0) --k;
    hull[k++] = points[i];
  }
  hull.resize(k - 1);
  // Drop vertices that are collinear with their neighbours or repeat them, within rounding.
  for (bool changed = true; changed && hull.size() > 3;) {
    changed = false;
    for (size_t i = 0; i < hull.size() && hull.size() > 3; ++i) {
      const Vector2d& prev = hull[(i + hull.size() - 1) % hull.size()];
      const Vector2d& next = hull[(i + 1) % hull.size()];
      const double base = (next - prev).norm();
      if ((hull[i] - prev).norm() <= 1e-12 || base == 0 || std::abs(Cross(prev, hull[i], next)) <= 1e-12 * base) {
        hull.erase(hull.begin() + static_cast<long>(i));
        changed = true;
      }
    }
  }
  return hull;
}

double MinWidth(const Polygon2& hull) {
  double width = std::numeric_limits<double>::infinity();
  for (size_t i = 0; i < hull.size(); ++i) {
    const Vector2d& a = hull[i];
    const Vector2d& b = hull[(i + 1) % hull.size()];
    const double len = (b - a).norm();
    if (len == 0) continue;
    double far = 0;
    for (const Vector2d& p : hull) far = std::max(far, Cross(a, b, p) / len);
    width = std::min(width, far);
  }
  return width;
}

Vector3d Transform(const Matrix4d& m, const Vector3d& p) { return m.block<3, 3>(0, 0) * p + m.block<3, 1>(0, 3); }

}  // namespace

Polyhedron MakePrism(const std::vector<Vector2d>& profile, double length) {
  Polyhedron model;
  const int n = static_cast<int>(profile.size());
  for (const Vector2d& p : profile) model.vertices.emplace_back(p.x(), -length / 2, p.y());
  for (const Vector2d& p : profile) model.vertices.emplace_back(p.x(), length / 2, p.y());
  std::vector<int> front(n), back(n);
  for (int i = 0; i < n; ++i) {
    front[i] = i;
    back[i] = n + (n - 1 - i);
  }
  model.faces.push_back(front);
  model.faces.push_back(back);
  for (int i = 0; i < n; ++i) {
    const int j = (i + 1) % n;
    model.faces.push_back({i, n + i, n + j, j});
  }
  return model;
}

Polyhedron MakeBox(const Vector3d& size) {
  const double x = size.x() / 2;
  // Profile bottom, right, top, left: sides are faces 2 (bottom), 3 (+x), 4 (top), 5 (−x) of the prism; reorder so
  // that faces 0 and 1 are bottom and top.
  Polyhedron prism = MakePrism({{-x, 0}, {x, 0}, {x, size.z()}, {-x, size.z()}}, size.y());
  Polyhedron box;
  box.vertices = prism.vertices;
  box.faces = {prism.faces[2], prism.faces[4], prism.faces[0], prism.faces[1], prism.faces[3], prism.faces[5]};
  return box;
}

std::string CheckPolyhedron(const Polyhedron& model, double planarity_tolerance) {
  if (model.vertices.size() < 4) return "a polyhedron needs at least 4 vertices";
  if (model.faces.size() < 4) return "a polyhedron needs at least 4 faces";
  for (size_t i = 0; i < model.vertices.size(); ++i) {
    if (!model.vertices[i].allFinite()) return fmt::format("vertex {} is not a finite number", i);
  }
  double volume = 0;
  for (size_t f = 0; f < model.faces.size(); ++f) {
    const std::vector<int>& face = model.faces[f];
    if (face.size() < 3) return fmt::format("face {} has {} vertices, needs at least 3", f, face.size());
    for (int v : face) {
      if (v < 0 || v >= static_cast<int>(model.vertices.size())) {
        return fmt::format("face {} refers to vertex {}, but there are {} vertices", f, v, model.vertices.size());
      }
    }
    for (size_t i = 0; i < face.size(); ++i) {
      if (face[i] == face[(i + 1) % face.size()]) return fmt::format("face {} repeats vertex {}", f, face[i]);
    }
    const Vector3d n2 = NewellNormal(model, face);
    if (n2.norm() <= 1e-18) return fmt::format("face {} has zero area", f);
    const Eigen::Vector4d plane = FacePlane(model, static_cast<int>(f));
    for (int v : face) {
      const double dist = plane.head<3>().dot(model.vertices[v]) + plane[3];
      if (std::abs(dist) > planarity_tolerance) {
        return fmt::format("face {} is not planar: vertex {} is {:.3g} m off the face's plane (tolerance {:.3g} m)", f,
                           v, dist, planarity_tolerance);
      }
    }
    for (size_t i = 1; i + 1 < face.size(); ++i) {
      volume += model.vertices[face[0]].dot(model.vertices[face[i]].cross(model.vertices[face[i + 1]])) / 6;
    }
  }
  if (volume <= 0) {
    return fmt::format("the faces enclose a volume of {:.3g} m^3: list each face counter-clockwise seen from outside",
                       volume);
  }
  return "";
}

Eigen::Vector4d FacePlane(const Polyhedron& model, int face) {
  const std::vector<int>& f = model.faces.at(face);
  const Vector3d n = NewellNormal(model, f).normalized();
  Vector3d centroid = Vector3d::Zero();
  for (int v : f) centroid += model.vertices[v];
  centroid /= static_cast<double>(f.size());
  return {n.x(), n.y(), n.z(), -n.dot(centroid)};
}

std::optional<FacePatch> FaceOverlap(const Polyhedron& a, const Matrix4d& wMa, int face_a, const Polyhedron& b,
                                     const Matrix4d& wMb, int face_b, double min_width) {
  const Eigen::Vector4d plane_b = FacePlane(b, face_b);
  const Vector3d nb = plane_b.head<3>();
  const std::vector<int>& fb = b.faces.at(face_b);
  const Vector3d origin = b.vertices[fb[0]];
  Vector3d u = Vector3d::Zero();
  for (size_t i = 1; i < fb.size() && u.norm() == 0; ++i) {
    const Vector3d edge = b.vertices[fb[i]] - origin;
    u = edge - nb * nb.dot(edge);
  }
  u.normalize();
  const Vector3d w = nb.cross(u);
  auto to2d = [&](const Vector3d& p) { return Vector2d(u.dot(p - origin), w.dot(p - origin)); };

  Polygon2 poly_b, poly_a;
  for (int v : fb) poly_b.push_back(to2d(b.vertices[v]));
  const Matrix4d bMa = RigidInverse(wMb) * wMa;
  for (int v : a.faces.at(face_a)) poly_a.push_back(to2d(Transform(bMa, a.vertices[v])));
  if (SignedArea(poly_b) < 0) std::reverse(poly_b.begin(), poly_b.end());
  if (SignedArea(poly_a) < 0) std::reverse(poly_a.begin(), poly_a.end());
  const double eps = 1e-12;
  Polygon2 pieces;
  for (const auto& ta : Triangulate(poly_a, eps)) {
    for (const auto& tb : Triangulate(poly_b, eps)) {
      const Polygon2 clip(tb.begin(), tb.end());
      for (const Vector2d& p : ClipConvex(Polygon2(ta.begin(), ta.end()), clip)) pieces.push_back(p);
    }
  }
  const Polygon2 hull = ConvexHull(pieces);
  if (hull.size() < 3) return std::nullopt;
  const double width = MinWidth(hull);
  if (!(width >= min_width) || width <= 0) return std::nullopt;
  FacePatch patch;
  patch.face = face_a;
  patch.against_face = face_b;
  patch.width = width;
  const Eigen::Vector4d plane_a = FacePlane(a, face_a);
  const Matrix4d aMb = RigidInverse(bMa);
  for (const Vector2d& p : hull) {
    const Vector3d point = origin + p.x() * u + p.y() * w;
    patch.points.push_back(point);
    patch.max_gap = std::max(patch.max_gap, std::abs(plane_a.head<3>().dot(Transform(aMb, point)) + plane_a[3]));
  }
  return patch;
}

double NormalQuantile(double p) {
  double lo = -40, hi = 40;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (0.5 * std::erfc(-mid / std::numbers::sqrt2) < p ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

namespace {

// The observables of a face pair at the poses wMa·ΔT(q_a), wMb·ΔT(q_b): the deviation of the normals from opposite
// (N_a + N_b along two directions t1, t2 of A's face plane, fixed), then the gap of every contact point (B's frame)
// to A's face plane.
Eigen::VectorXd PairObservables(const Polyhedron& a, const Matrix4d& wMa, int fa, const Polyhedron& b,
                                const Matrix4d& wMb, int fb, const std::vector<Vector3d>& points, const Vector3d& t1,
                                const Vector3d& t2, const Eigen::Matrix<double, 12, 1>& q) {
  const Matrix4d ma = wMa * DeltaTransform(q.head<6>());
  const Matrix4d mb = wMb * DeltaTransform(q.tail<6>());
  const Eigen::Vector4d plane_a = FacePlane(a, fa);
  const Vector3d sum = ma.block<3, 3>(0, 0) * plane_a.head<3>() + mb.block<3, 3>(0, 0) * FacePlane(b, fb).head<3>();
  Eigen::VectorXd out(2 + static_cast<Eigen::Index>(points.size()));
  out[0] = t1.dot(sum);
  out[1] = t2.dot(sum);
  const Matrix4d aMb = RigidInverse(ma) * mb;
  for (size_t i = 0; i < points.size(); ++i) {
    out[2 + static_cast<Eigen::Index>(i)] = plane_a.head<3>().dot(Transform(aMb, points[i])) + plane_a[3];
  }
  return out;
}

// Covariance of PairObservables at q = 0: J Σ Jᵀ, J by central differences (steps 1e-7 m, 1e-6 rad; the observables
// are smooth products of rotations and positions of order 1, truncation and rounding errors ~1e-10 relative).
Eigen::MatrixXd ObservableCovariance(const Polyhedron& a, const Matrix4d& wMa, int fa, const Polyhedron& b,
                                     const Matrix4d& wMb, int fb, const std::vector<Vector3d>& points,
                                     const Vector3d& t1, const Vector3d& t2, const PairCovariance& covariance) {
  Eigen::MatrixXd jac(2 + static_cast<Eigen::Index>(points.size()), 12);
  for (int k = 0; k < 12; ++k) {
    const double h = k % 6 < 3 ? 1e-7 : 1e-6;
    Eigen::Matrix<double, 12, 1> q = Eigen::Matrix<double, 12, 1>::Zero();
    q[k] = h;
    const Eigen::VectorXd plus = PairObservables(a, wMa, fa, b, wMb, fb, points, t1, t2, q);
    q[k] = -h;
    jac.col(k) = (plus - PairObservables(a, wMa, fa, b, wMb, fb, points, t1, t2, q)) / (2 * h);
  }
  return jac * covariance * jac.transpose();
}

}  // namespace

std::vector<FacePatch> FindFaceContacts(const Polyhedron& a, const Matrix4d& wMa, const Polyhedron& b,
                                        const Matrix4d& wMb, const ContactThresholds& thresholds,
                                        const PairCovariance* covariance) {
  if (covariance != nullptr && covariance->cwiseAbs().maxCoeff() > 0) {
    // Derived thresholds. A true contact's observables are zero-mean Gaussian with covariance C = J Σ Jᵀ (first
    // order). Angle: the normals' deviation δ (2 dof) is accepted while δᵀ C_δ⁻¹ δ ≤ χ²₂(1 − α/2) = −2 ln(α/2).
    // Gaps: each of the m contact points while |g_i| ≤ k σ_i, k = Φ⁻¹(1 − α/(4m)) (two-sided, Bonferroni over the
    // points). So a true contact is missed with probability ≤ α. Floors: min_angle_deg, min_distance.
    const double alpha = thresholds.false_miss_probability;
    const double chi2 = -2 * std::log(alpha / 2);
    const double floor_angle = thresholds.min_angle_deg * std::numbers::pi / 180.0;
    std::vector<FacePatch> patches;
    for (int fa = 0; fa < static_cast<int>(a.faces.size()); ++fa) {
      const Vector3d na = wMa.block<3, 3>(0, 0) * FacePlane(a, fa).head<3>();
      const Vector3d t1 = na.unitOrthogonal(), t2 = na.cross(t1);
      for (int fb = 0; fb < static_cast<int>(b.faces.size()); ++fb) {
        const Vector3d nb = wMb.block<3, 3>(0, 0) * FacePlane(b, fb).head<3>();
        if (na.dot(nb) >= 0) continue;  // more than 90° from opposite: no noise model makes that a contact
        std::optional<FacePatch> patch = FaceOverlap(a, wMa, fa, b, wMb, fb, thresholds.min_width);
        if (!patch) continue;
        const Eigen::MatrixXd c = ObservableCovariance(a, wMa, fa, b, wMb, fb, patch->points, t1, t2, *covariance);
        const Eigen::Vector2d delta(t1.dot(na + nb), t2.dot(na + nb));
        const double angle = std::acos(std::clamp(-na.dot(nb), -1.0, 1.0));
        if (angle > floor_angle) {
          const Eigen::Matrix2d cd = c.topLeftCorner<2, 2>();
          const Eigen::LDLT<Eigen::Matrix2d> ldlt(cd);
          if (cd.determinant() <= 0 || !(delta.dot(ldlt.solve(delta)) <= chi2)) continue;
        }
        const int m = static_cast<int>(patch->points.size());
        const double k = NormalQuantile(1 - alpha / (4.0 * m));
        bool touching = true;
        double worst_threshold = 0;
        const Matrix4d aMb = RigidInverse(wMa) * wMb;
        const Eigen::Vector4d plane_a = FacePlane(a, fa);
        for (int i = 0; i < m; ++i) {
          const double gap = plane_a.head<3>().dot(Transform(aMb, patch->points[static_cast<size_t>(i)])) + plane_a[3];
          const double threshold = std::max(thresholds.min_distance, k * std::sqrt(std::max(0.0, c(2 + i, 2 + i))));
          worst_threshold = std::max(worst_threshold, threshold);
          touching = touching && std::abs(gap) <= threshold;
        }
        if (!touching) continue;
        patch->distance_threshold = worst_threshold;
        patches.push_back(std::move(*patch));
      }
    }
    return patches;
  }
  std::vector<FacePatch> patches;
  const double cos_limit = std::cos(thresholds.angle_deg * std::numbers::pi / 180.0);
  for (int fa = 0; fa < static_cast<int>(a.faces.size()); ++fa) {
    const Vector3d na = wMa.block<3, 3>(0, 0) * FacePlane(a, fa).head<3>();
    for (int fb = 0; fb < static_cast<int>(b.faces.size()); ++fb) {
      const Vector3d nb = wMb.block<3, 3>(0, 0) * FacePlane(b, fb).head<3>();
      if (na.dot(nb) > -cos_limit) continue;
      std::optional<FacePatch> patch = FaceOverlap(a, wMa, fa, b, wMb, fb, thresholds.min_width);
      if (patch && patch->max_gap <= thresholds.distance) {
        patch->distance_threshold = thresholds.distance;
        patches.push_back(std::move(*patch));
      }
    }
  }
  return patches;
}

}  // namespace visco::face_contact
