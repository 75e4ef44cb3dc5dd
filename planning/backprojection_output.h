#pragma once
// The output of a directional backprojection (docs/formats.md): the region JSON, the `visco backproject` document and
// its picture.

#include <string>

#include "planning/backprojection.h"
#include "planning/scene.h"

namespace visco::planning {

class CSpace;

std::string RegionToJson(const Region& region, int indent = -1);

/// The `visco backproject` document: {"theta_deg", "classic": REGION, "vc": REGION + {"active_rays": [...]}}.
std::string BackprojectionToJson(double theta_deg, const Region& classic, const VcBackprojection& vc);

/// Fig. 13-style picture: classic (left) and VC-enlarged (right) side by side; workspace obstacles shaded,
/// C-obstacles outlined, goal black, camera a cross, commanded velocity an arrow, the region dashed with VC edges
/// bold.
std::string BackprojectionToSvg(const Scene& scene, const CSpace& cspace, const BackprojectionProblem& problem,
                                const Region& classic, const VcBackprojection& vc);

}  // namespace visco::planning
