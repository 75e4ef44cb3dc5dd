#include "app/demo/monte_carlo.h"

#include <algorithm>
#include <cmath>
#include <random>

namespace visco::app::demo {

std::vector<Eigen::Vector2d> SampleStarts(const planning::Polygon& region, int runs, std::uint64_t seed) {
  const auto& sv = region.vertices;
  Eigen::Vector2d centroid = Eigen::Vector2d::Zero();
  for (const auto& v : sv) centroid += v / static_cast<double>(sv.size());
  if (runs == 1) return {centroid};
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(0, 1);
  Eigen::Vector2d lo = sv[0], hi = sv[0];
  for (const auto& v : sv) lo = lo.cwiseMin(v), hi = hi.cwiseMax(v);
  double perimeter = 0;
  for (size_t i = 0; i < sv.size(); ++i) perimeter += (sv[(i + 1) % sv.size()] - sv[i]).norm();
  std::vector<Eigen::Vector2d> starts;
  for (int r = 0; r < runs; ++r) {
    Eigen::Vector2d q = centroid;
    if (r % 4 == 3) {
      double along = u(rng) * perimeter;
      for (size_t i = 0; i < sv.size(); ++i) {
        const Eigen::Vector2d a = sv[i], b = sv[(i + 1) % sv.size()];
        const double len = (b - a).norm();
        if (along <= len || i + 1 == sv.size()) {
          q = a + (b - a) * std::clamp(along / len, 0.0, 1.0);
          break;
        }
        along -= len;
      }
    } else {
      for (int k = 0; k < 1000; ++k) {
        const Eigen::Vector2d p(lo.x() + u(rng) * (hi.x() - lo.x()), lo.y() + u(rng) * (hi.y() - lo.y()));
        if (planning::InsideEvenOdd(sv, p)) {
          q = p;
          break;
        }
      }
    }
    starts.push_back(q);
  }
  return starts;
}

double Quantile(std::vector<double> v, double q) {
  if (v.empty()) return NAN;
  std::sort(v.begin(), v.end());
  const double at = q * static_cast<double>(v.size() - 1);
  const size_t i = static_cast<size_t>(std::floor(at));
  const size_t j = std::min(i + 1, v.size() - 1);
  return v[i] + (v[j] - v[i]) * (at - static_cast<double>(i));
}

nlohmann::json Quantiles(const std::vector<double>& v) {
  auto q = [&](double p) { return v.empty() ? nlohmann::json() : nlohmann::json(Quantile(v, p)); };
  return nlohmann::json{{"min", q(0)}, {"p05", q(0.05)}, {"median", q(0.5)}, {"p95", q(0.95)}, {"max", q(1)}};
}

}  // namespace visco::app::demo
