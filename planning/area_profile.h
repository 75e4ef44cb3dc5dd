#pragma once
// The area profile of a nondirectional backprojection: the areas of B_θ(G) and B_vcθ(G) against θ, and its picture
// with the critical orientations (`visco critical --svg`, docs/formats.md).

#include <string>
#include <vector>

#include "planning/nondirectional.h"

namespace visco::planning {

/// The areas at one commanded direction.
struct AreaSample {
  double theta = 0.0;
  double classic = 0.0;
  double vc = 0.0;
};

/// Areas of B_θ(G) and B_vcθ(G) (with the active rays of the slice standing for θ) at `samples` evenly spaced θ, at
/// every critical slice and just inside both ends of every open interval, sorted by θ. No sweep: the open slices'
/// regions are carried to each θ (RegionAt).
std::vector<AreaSample> SampleAreas(const NondirectionalBackprojection& nd, int samples);

/// The area-against-θ picture: both curves, a vertical line per orientation coloured by kind, a legend.
std::string AreaProfileSvg(const std::string& title, const std::vector<AreaSample>& samples,
                           const std::vector<CriticalOrientation>& orientations);

}  // namespace visco::planning
