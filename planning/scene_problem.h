#pragma once
// The backprojection problem of a scene (backprojection.h): the planner, the commands and the tests build it the same
// way from a scene, its C-space and its visual-constraint rays.

#include <vector>

#include "planning/backprojection.h"
#include "planning/scene.h"

namespace visco::planning {

class CSpace;
struct VcRays;

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

/// The CVC rays of a scene as backprojection candidates (id, group = the VC ray's id, free-space segments).

}  // namespace visco::planning
