#pragma once
// `visco backproject SCENE --theta DEG [--kernel] [--out FILE] [--svg FILE]` (docs/formats.md), and the pieces it is
// made of, for tests and for the planner: the backprojection problem of a scene, the region JSON, the picture.

#include <string>
#include <vector>

#include "planning/backprojection.h"
#include "planning/scene.h"

namespace CLI {
class App;
}

namespace visco::planning {

class CSpace;
struct VcRays;

/// Registers `visco backproject` on `app`.
void RegisterBackprojectCommand(CLI::App& app);

/// The backprojection problem of a scene for commanded direction θ (radians): CB, the union of the C-obstacles
/// (CSpace::obstacle_union, holes included), with the refs of the Minkowski features its edges and vertices lie on
/// (CSpace::obstacle_union_sources: "obstacle[ID].e[i]-robot.v[j]", "obstacle[ID].v[i]-robot.e[j]",
/// "obstacle[ID].v[i]-robot.v[j]", "x(<ref>,<ref>)"; file positions, the same at every θ), the goal (refs
/// "goal.e[i]" / "goal.v[i]", file positions) or, with `kernel`, its kernel
/// (GoalKernel with the scene's position uncertainty), the bounds, and every CVC ray (id, group = its VC ray).
BackprojectionProblem ProblemFromScene(const Scene& scene, const CSpace& cspace, const VcRays* rays, double theta,
                                       bool kernel);

/// The CVC rays of a scene as backprojection candidates (id, group = the VC ray's id, free-space segments).
std::vector<CvcRayInput> CvcRayInputs(const VcRays& rays);

/// docs/formats.md region JSON: {"area", "regions": [{"outer": {"vertices", "edges": [{"kind", "ref"}]}, "holes"}]}.
std::string RegionToJson(const Region& region, int indent = -1);

/// The `visco backproject` document: {"theta_deg", "classic": REGION, "vc": REGION + {"active_rays": [...]}}.
std::string BackprojectionToJson(double theta_deg, const Region& classic, const VcBackprojection& vc);

/// Fig. 13-style picture: classic (left) and VC-enlarged (right) side by side; workspace obstacles shaded,
/// C-obstacles outlined, goal black, camera a cross, commanded velocity an arrow, the region dashed with VC edges
/// bold.
std::string BackprojectionToSvg(const Scene& scene, const CSpace& cspace, const BackprojectionProblem& problem,
                                const Region& classic, const VcBackprojection& vc);

}  // namespace visco::planning
