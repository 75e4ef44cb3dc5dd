#include "vision/contact_refinement.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "planning/flush_poses.h"

namespace visco::vision {

PrismMesh ObjectPrism(const ObjectModel& model) {
  // planning::MakePrism extrudes a profile (x, z) along y; turned by Rx(-90 deg) ((x, y, z) -> (x, z, -y), a proper
  // rotation: faces stay outward) and lifted by height / 2, it is the vertical prism over the polygon.
  std::vector<Eigen::Vector2d> profile = model.polygon;
  double area2 = 0;
  for (std::size_t i = 0; i < profile.size(); ++i) {
    const auto& a = profile[i];
    const auto& b = profile[(i + 1) % profile.size()];
    area2 += a.x() * b.y() - a.y() * b.x();
  }
  if (area2 < 0) std::reverse(profile.begin(), profile.end());  // MakePrism wants counter-clockwise
  const planning::Polyhedron p = planning::MakePrism(profile, model.height);
  PrismMesh mesh;
  for (const auto& v : p.vertices) mesh.vertices.emplace_back(v.x(), v.z(), -v.y() + model.height / 2);
  mesh.faces = p.faces;
  return mesh;
}

ContactRefinement RefineContacts(const std::vector<ContactObject>& objects, const ContactOptions& options) {
  ContactRefinement out;
  for (const auto& o : objects) out.wMo.push_back(o.wMo);
  out.in_contact.assign(objects.size(), false);
  if (!options.enabled || objects.empty()) {
    out.message = "contact refinement off";
    return out;
  }
  std::vector<planning::FlushObject> flush;
  double sigma_pos = 0, sigma_rot = 0;
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(1e18), hi = Eigen::Vector2d::Constant(-1e18);
  for (const auto& o : objects) {
    const PrismMesh mesh = ObjectPrism(*o.model);
    planning::FlushObject f;
    f.id = o.model->id;
    f.model.vertices = mesh.vertices;
    f.model.faces = mesh.faces;
    f.pose = o.wMo;
    flush.push_back(std::move(f));
    sigma_pos = std::max(sigma_pos, o.position_stddev);
    sigma_rot = std::max(sigma_rot, o.orientation_stddev);
    for (const auto& v : mesh.vertices) {
      const Eigen::Vector2d w = (o.wMo * v).head<2>();
      lo = lo.cwiseMin(w), hi = hi.cwiseMax(w);
    }
  }
  // The table: a stable box under everything in view, its top face the plane z = 0.
  planning::FlushObject table;
  table.id = "table";
  table.stable = true;
  const Eigen::Vector2d size = (hi - lo).array() + 1.0;
  table.model = planning::MakeBox(Eigen::Vector3d(size.x(), size.y(), options.table_thickness_m));
  table.pose.translation() << (lo + hi) / 2, -options.table_thickness_m;
  flush.push_back(table);

  planning::FlushOptions fo;
  fo.contact.distance = std::max(options.min_distance_m, options.k_sigma * sigma_pos);
  fo.contact.angle_deg = std::max(options.min_angle_deg, options.k_sigma * sigma_rot * 180 / M_PI);
  planning::FlushResult r;
  try {
    r = planning::MakeFlush(flush, fo);
  } catch (const std::invalid_argument& e) {
    out.message = e.what();
    return out;
  }
  out.contacts = static_cast<int>(r.contacts.size());
  out.observed_gap_m = r.report.observed_max_residue;
  out.max_residue_m = r.report.max_residue;
  out.message = r.message;
  if (!r.ok || r.contacts.empty()) return out;
  out.ok = true;
  for (const auto& c : r.contacts) {
    if (c.object < static_cast<int>(objects.size())) out.in_contact[static_cast<std::size_t>(c.object)] = true;
    if (c.against < static_cast<int>(objects.size())) out.in_contact[static_cast<std::size_t>(c.against)] = true;
  }
  for (std::size_t i = 0; i < objects.size(); ++i) out.wMo[i] = r.poses[i];
  return out;
}

}  // namespace visco::vision
