#pragma once
// The sweep frame (internal to the directional backprojection): the similarity that turns the commanded velocity
// straight down, applied exactly, and the frame of one θ shared by every sweep at that θ.

#include <gmpxx.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <type_traits>
#include <utility>

#include "planning/backprojection/exact.h"

namespace visco::planning::internal {

// a·x − b·y exactly, for doubles: each product of two doubles is an integer times a power of two, and so is their
// difference, which is then in lowest terms once the numerator's trailing zero bits are taken into the power (no
// gcd, which the general rational arithmetic computes after every operation). The same number as
// ET(a) * ET(x) − ET(b) * ET(y).
inline FT::ET DyadicDifference(double a, double x, double b, double y) {
  using ET = FT::ET;
  static_assert(std::is_same_v<ET, mpq_class>, "the lazy kernel's exact numbers are GMP rationals");
  if (!std::isfinite(a) || !std::isfinite(x) || !std::isfinite(b) || !std::isfinite(y)) {
    return ET(ET(a) * ET(x) - ET(b) * ET(y));  // not reached for a scene's numbers; as before
  }
  // d = m · 2^e with m an integer of at most 53 bits.
  auto split = [](double d, mpz_class& m, long& e) {
    int exponent = 0;
    const double fraction = std::frexp(d, &exponent);
    m = static_cast<long>(std::ldexp(fraction, 53));
    e = static_cast<long>(exponent) - 53;
  };
  mpz_class ma, mx, mb, my;
  long ea = 0, ex = 0, eb = 0, ey = 0;
  split(a, ma, ea);
  split(x, mx, ex);
  split(b, mb, eb);
  split(y, my, ey);
  mpz_class p = ma * mx, q = mb * my;
  const long ep = ea + ex, eq = eb + ey, e = std::min(ep, eq);
  mpz_mul_2exp(p.get_mpz_t(), p.get_mpz_t(), static_cast<mp_bitcnt_t>(ep - e));
  mpz_mul_2exp(q.get_mpz_t(), q.get_mpz_t(), static_cast<mp_bitcnt_t>(eq - e));
  mpz_class n = p - q;  // the result is n · 2^e
  ET out;
  if (sgn(n) == 0) return out;
  if (e >= 0) {
    mpz_mul_2exp(n.get_mpz_t(), n.get_mpz_t(), static_cast<mp_bitcnt_t>(e));
    out.get_num() = n;
    return out;
  }
  const mp_bitcnt_t zeros = std::min<mp_bitcnt_t>(mpz_scan1(n.get_mpz_t(), 0), static_cast<mp_bitcnt_t>(-e));
  mpz_tdiv_q_2exp(n.get_mpz_t(), n.get_mpz_t(), zeros);  // exact: those bits are zero
  out.get_num() = n;
  mpz_class den = 1;
  mpz_mul_2exp(den.get_mpz_t(), den.get_mpz_t(), static_cast<mp_bitcnt_t>(-e) - zeros);
  out.get_den() = den;
  return out;
}

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
    return P2(FT(DyadicDifference(c, p.x(), s, p.y())), FT(DyadicDifference(s, p.x(), -c, p.y())));
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
