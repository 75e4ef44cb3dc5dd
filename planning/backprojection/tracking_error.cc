// The tracking error's geometry (tracking_error.h) and TrackingErrorCuts (backprojection.h).

#include "planning/backprojection/tracking_error.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "planning/geometry.h"

namespace visco::planning::internal {

bool PieceWithinTrackingError(const Vector2d& a, const Vector2d& b, const Vector2d& up, const Vector2d& down,
                              double delta, double& t0, double& t1) {
  const Vector2d d = down - up;
  const Vector2d n = Vector2d(-d.y(), d.x()).normalized();
  // Signed distance from the line: da + s (db − da) for s in [0, 1]; keep |·| <= δ.
  const double da = (a - up).dot(n), db = (b - up).dot(n);
  double s0 = 0.0, s1 = 1.0;
  if (da != db) {
    const double lo = (-delta - da) / (db - da), hi = (delta - da) / (db - da);
    s0 = std::max(s0, std::min(lo, hi));
    s1 = std::min(s1, std::max(lo, hi));
  } else if (std::abs(da) > delta) {
    return false;
  }
  if (s0 > s1) return false;
  t0 = (a + s0 * (b - a) - up).dot(d) / d.squaredNorm();
  t1 = (a + s1 * (b - a) - up).dot(d) / d.squaredNorm();
  return true;
}

std::vector<double> PointsWithinTrackingError(const BackprojectionProblem& pr, const Vector2d& up, const Vector2d& down,
                                              double snap, bool& to_the_end,
                                              std::vector<std::pair<double, double>>& pieces) {
  const double delta = pr.ray_tracking_error;
  std::vector<double> breaks;
  to_the_end = false;
  auto consider = [&](const Vector2d& a, const Vector2d& b) {
    double t0, t1;
    if (!PieceWithinTrackingError(a, b, up, down, delta, t0, t1)) return;
    if (std::max(t0, t1) <= 0.0 || std::min(t0, t1) >= 1.0) return;  // beside the line beyond the ray's ends
    to_the_end = to_the_end || std::max(t0, t1) >= 1.0;
    pieces.emplace_back(std::min(t0, t1), std::max(t0, t1));
    for (const double t : {t0, t1}) {
      if (t > 0.0 && t < 1.0) breaks.push_back(t);
    }
  };
  for (const auto& poly : pr.obstacles) {
    const size_t nv = poly.vertices.size();
    for (size_t i = 0; i < nv; ++i) {
      const Vector2d& a = poly.vertices[i];
      const Vector2d& b = poly.vertices[(i + 1) % nv];
      if (PointSegmentDistance(up, a, b) <= snap || PointSegmentDistance(down, a, b) <= snap) continue;
      consider(a, b);
    }
  }
  // The bounds and the forbidden regions too, ends or not: the robot beside the line can leave the allowed
  // configurations there (VISCO_SEED_OFFSET=8636742, seed 14 of the goal-on-CB soundness scenes: a ray starting on
  // the bounds, the robot joining it 1 cm inside them with δ = 2.3 cm).
  const Vector2d lo = pr.bounds_min, hi = pr.bounds_max;
  const Vector2d corners[4] = {{lo.x(), lo.y()}, {hi.x(), lo.y()}, {hi.x(), hi.y()}, {lo.x(), hi.y()}};
  for (int k = 0; k < 4; ++k) consider(corners[k], corners[(k + 1) % 4]);
  for (const auto& poly : pr.forbidden) {
    const size_t nv = poly.vertices.size();
    for (size_t i = 0; i < nv; ++i) consider(poly.vertices[i], poly.vertices[(i + 1) % nv]);
  }
  std::sort(breaks.begin(), breaks.end());
  breaks.erase(std::unique(breaks.begin(), breaks.end(), [](double x, double y) { return y - x <= 1e-12; }),
               breaks.end());
  return breaks;
}

bool GoalAfterTheLanding(const BackprojectionProblem& pr, const Vector2d& up, const Vector2d& down, double snap) {
  const Vector2d d = down - up;
  const double len2 = d.squaredNorm();
  if (!(len2 > 0.0)) return false;
  const double delta = pr.ray_tracking_error;
  double landing = 1.0;  // the ray parameter where a landing edge first comes within δ
  for (const auto& poly : pr.obstacles) {
    const size_t nv = poly.vertices.size();
    for (size_t i = 0; i < nv; ++i) {
      const Vector2d& a = poly.vertices[i];
      const Vector2d& b = poly.vertices[(i + 1) % nv];
      double t0, t1;
      if (PointSegmentDistance(down, a, b) > snap || !PieceWithinTrackingError(a, b, up, down, delta, t0, t1)) continue;
      landing = std::min({landing, t0, t1});
    }
  }
  if (!(landing < 1.0)) return false;
  double goal = 1.0;  // the ray parameter where the part first meets the goal's boundary
  for (const auto& poly : pr.goal) {
    const size_t nv = poly.vertices.size();
    for (size_t i = 0; i < nv; ++i) {
      const Vector2d& a = poly.vertices[i];
      const Vector2d e = poly.vertices[(i + 1) % nv] - a;
      const double denom = d.x() * e.y() - d.y() * e.x();
      if (denom == 0.0) continue;
      const Vector2d w = a - up;
      const double t = (w.x() * e.y() - w.y() * e.x()) / denom, u = (w.x() * d.y() - w.y() * d.x()) / denom;
      if (t >= 0.0 && t < goal && u >= 0.0 && u <= 1.0) goal = t;
    }
  }
  return goal < 1.0 && goal > landing;
}
}  // namespace visco::planning::internal

namespace visco::planning {

using Eigen::Vector2d;
using internal::PointsWithinTrackingError;

std::vector<Vector2d> TrackingErrorCuts(const BackprojectionProblem& problem, const Vector2d& a, const Vector2d& b) {
  std::vector<Vector2d> cuts;
  if (!(problem.ray_tracking_error > 0.0) || a == b) return cuts;
  const double snap = 1e-9 * (problem.bounds_max - problem.bounds_min).norm();
  bool to_the_end = false;
  std::vector<std::pair<double, double>> pieces;
  for (const double t : PointsWithinTrackingError(problem, a, b, snap, to_the_end, pieces))
    cuts.push_back(a + t * (b - a));
  return cuts;
}

}  // namespace visco::planning
