#pragma once
// The servo's tracking error δ around an active ray (docs/semantics.md, "Compliance ends"): where C-obstacles, the
// bounds and forbidden regions come within δ of the ray's line (internal to the directional backprojection; in a
// header so that it can be unit tested). Plain double geometry: no exact arithmetic.

#include <Eigen/Core>
#include <utility>
#include <vector>

#include "planning/backprojection.h"

namespace visco::planning::internal {

using Eigen::Vector2d;

// The points of segment [a, b] within δ of the line through `up` and `down` form one piece (the distance is affine
// along the segment): false if there are none, else the piece's ends as parameters along the line (0 at up, 1 at
// down), in any order.
bool PieceWithinTrackingError(const Vector2d& a, const Vector2d& b, const Vector2d& up, const Vector2d& down,
                              double delta, double& t0, double& t1);

// Where along the ray from `up` to `down` (0 at up, 1 at down) the C-obstacles (their edges that neither end lies on,
// within `snap`), the bounds and the forbidden regions come within the tracking error δ of its line beside the ray:
// each edge's points within δ of the line form one piece of it (PieceWithinTrackingError); returns the parameters in
// (0, 1) where such pieces begin and end, ascending, and sets `to_the_end` where one runs on to the lower end or past
// it; `pieces` gets each piece's parameter range.
std::vector<double> PointsWithinTrackingError(const BackprojectionProblem& pr, const Vector2d& up, const Vector2d& down,
                                              double snap, bool& to_the_end,
                                              std::vector<std::pair<double, double>>& pieces);

// With the servo's tracking error the robot can meet the edges a closed lower end `down` lies on (its landing) up to
// δ / sin(angle) before the end. The sweep checks the landing at the end (LandingIsGood), but where the ray enters
// the goal on the way there it stops at the goal and never looks. True if the part from `up` enters the goal only
// after a landing edge has come within δ of its line: the robot may meet the edge first (seed 29 of the soundness
// test's goal-on-CB scenes, once the simulator met landing edges where the robot joins a ray).
bool GoalAfterTheLanding(const BackprojectionProblem& pr, const Vector2d& up, const Vector2d& down, double snap);

}  // namespace visco::planning::internal
