#include "face_contact/flush_poses.h"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <stdexcept>

namespace visco::face_contact {

FlushResult MakeFlush(const std::vector<FlushObject>& objects, const FlushOptions& options) {
  FlushResult result;
  ContactProblem problem;
  std::vector<int> param(objects.size());
  for (size_t i = 0; i < objects.size(); ++i) {
    const FlushObject& o = objects[i];
    double diameter = 0;
    for (const auto& v : o.model.vertices) diameter = std::max(diameter, v.norm() * 2);
    const std::string problem_text = CheckPolyhedron(o.model, 1e-9 * std::max(1.0, diameter));
    if (!problem_text.empty()) {
      throw std::invalid_argument(fmt::format("MakeFlush: object {} ('{}'): {}", i, o.id, problem_text));
    }
    const Eigen::Matrix3d r = o.pose.linear();
    if (!o.pose.matrix().allFinite() ||
        (r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() > 1e-6 || r.determinant() <= 0) {
      throw std::invalid_argument(fmt::format("MakeFlush: object {} ('{}'): the pose is not rigid", i, o.id));
    }
    param[i] = static_cast<int>(problem.params.size());
    problem.params.push_back(o.pose.matrix());
    if (!o.stable) problem.variables.push_back(param[i]);
  }
  for (size_t j = 0; j < objects.size(); ++j) {
    for (size_t i = 0; i < j; ++i) {
      if (objects[i].stable && objects[j].stable) continue;
      // Face side: the non-stable object; the later one when both move.
      const size_t a = objects[j].stable ? i : j;
      const size_t b = a == j ? i : j;
      PairCovariance covariance = PairCovariance::Zero();
      covariance.topLeftCorner<6, 6>() = objects[a].covariance;
      covariance.bottomRightCorner<6, 6>() = objects[b].covariance;
      const bool derived = covariance.cwiseAbs().maxCoeff() > 0;
      for (const FacePatch& patch :
           FindFaceContacts(objects[a].model, problem.params[param[a]], objects[b].model, problem.params[param[b]],
                            options.contact, derived ? &covariance : nullptr)) {
        ContactGroup g;
        g.chain = {{param[a], true}, {param[b], false}};
        g.plane = FacePlane(objects[a].model, patch.face);
        g.points = patch.points;
        g.tag = static_cast<int>(result.contacts.size());
        problem.groups.push_back(std::move(g));
        result.contacts.push_back(
            {static_cast<int>(a), patch.face, static_cast<int>(b), patch.against_face, patch.max_gap});
      }
    }
  }
  result.report = SolveContacts(problem, options.solver);
  result.ok = result.report.status == SolveStatus::kConverged;
  for (size_t i = 0; i < objects.size(); ++i) {
    Eigen::Isometry3d pose = objects[i].pose;
    if (result.ok) pose.matrix() = result.report.corrected[param[i]];
    result.poses.push_back(pose);
  }
  result.message = fmt::format("{} face contact(s) among {} objects: {}", result.contacts.size(), objects.size(),
                               result.report.message);
  return result;
}

}  // namespace visco::face_contact
