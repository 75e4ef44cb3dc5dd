#pragma once
// The sweep frame (internal to the directional backprojection): the similarity that turns the commanded velocity
// straight down, applied exactly, and the frame of one θ shared by every sweep at that θ.

#include <cmath>
#include <map>
#include <utility>

#include "planning/backprojection/exact.h"

namespace visco::planning::internal {

struct Rotation {
  using ET = FT::ET;  // the exact rational type behind the lazy kernel
  double c = 1, s = 0;
  ET ec = 1, es = 0, det = 1;  // c, s and c² + s² exactly
  Rotation() = default;
  Rotation(double c_in, double s_in) : c(c_in), s(s_in), ec(c_in), es(s_in), det(ec * ec + es * es) {}
  Vector2d Apply(const Vector2d& p) const { return {c * p.x() - s * p.y(), s * p.x() + c * p.y()}; }
  // The sweep frame is the similarity [[c, -s], [s, c]] applied exactly (not rounded): collinear and touching input
  // edges stay collinear and touching. Computed in plain rationals, so the lazy point carries its exact value from
  // the start (no construction DAG for each predicate that the interval filter cannot decide to re-evaluate).
  P2 ApplyExact(const Vector2d& p) const {
    const ET x(p.x()), y(p.y());
    return P2(FT(ET(ec * x - es * y)), FT(ET(es * x + ec * y)));
  }
  // The exact inverse, converted to double once (CGAL::to_double of the exact value).
  Vector2d InvertExact(const P2& p) const {
    const FT px = p.x(), py = p.y();  // kept alive: exact() refers into them
    const ET& x = CGAL::exact(px);
    const ET& y = CGAL::exact(py);
    return {CGAL::to_double(ET((ec * x + es * y) / det)), CGAL::to_double(ET((ec * y - es * x) / det))};
  }
  FT Scale2() const { return FT(det); }  // the similarity's area factor
};

// The sweep frame of one θ, shared by every sweep at that θ (the ray choice runs up to 3k + 1 of them): each world
// point is mapped once, so equal world points are one exact point in every sweep and their comparisons, which the
// interval filter cannot decide, reuse one exact value instead of rebuilding it.
class SweepFrame {
 public:
  explicit SweepFrame(double theta) : rot_(std::cos(-M_PI / 2 - theta), std::sin(-M_PI / 2 - theta)) {}
  const Rotation& rotation() const { return rot_; }
  const P2& Map(const Vector2d& w) {
    auto [it, inserted] = points_.try_emplace({w.x(), w.y()});
    if (inserted) it->second = rot_.ApplyExact(w);
    return it->second;
  }

 private:
  Rotation rot_;
  std::map<std::pair<double, double>, P2> points_;
};

}  // namespace visco::planning::internal
