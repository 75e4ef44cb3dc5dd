#pragma once
// Monte Carlo runs of the demo (--runs): where they start, and the statistics of their outcomes.

#include <Eigen/Core>
#include <cstdint>
#include <nlohmann/json.hpp>
#include <vector>

#include "planning/geometry.h"

namespace visco::app::demo {

/// The starts: the start region's centroid for one run; for Monte Carlo, seeded points of the start region, every
/// fourth on its boundary (the strategy is guaranteed for the closed region, its boundary included).
std::vector<Eigen::Vector2d> SampleStarts(const planning::Polygon& region, int runs, std::uint64_t seed);

/// The q-quantile of `v` (linear interpolation between order statistics); NaN when `v` is empty.
double Quantile(std::vector<double> v, double q);

/// {"min", "p05", "median", "p95", "max"} of `v` (nulls when it is empty), as summary.json gives them.
nlohmann::json Quantiles(const std::vector<double>& v);

}  // namespace visco::app::demo
