#pragma once
// What the camera looks at: the robot and the obstacles as vertical prisms standing on the table (world z = 0),
// with the AprilTags fixed on them, and the CM-vertex / obstacle-vertex pairs whose visual events are wanted.
//
// File (JSON, same conventions as scenes: metres, degrees, unknown fields are an error):
// {
//   "robot": {"id": "robot", "polygon": [[x, y], ...], "height": 0.03,
//             "tags": [{"family": "tag36h11", "id": 0, "size": 0.04, "t": [x, y, z], "rpy_deg": [r, p, y]}]},
//   "obstacles": [{"id": "left", "polygon": [...], "height": 0.05, "tags": [...]}],
//   "events": [{"cvc_ray": "vc0.cm1", "obstacle": "left", "vertex": 2, "cm_vertex": 1}]
// }
// Polygons are in the object frame (its origin on the table, z up); a tag's "t"/"rpy_deg" give its pose oMt in the
// object frame (a tag lying on the top face, face up: t = [x, y, height], rpy_deg = [0, 0, yaw]). "events" is
// optional: without it, every robot vertex is paired with every obstacle vertex ("<obstacle>.v<j>.cm<i>").

#include <Eigen/Geometry>
#include <string>
#include <vector>

namespace visco::vision {

/// An AprilTag mounted on an object.
struct TagMount {
  std::string family = "tag36h11";
  int id = 0;
  double size = 0;                                        ///< metres, black border's outer edge
  Eigen::Isometry3d oMt = Eigen::Isometry3d::Identity();  ///< tag frame in the object frame
};

/// A vertical prism standing on the table.
struct ObjectModel {
  std::string id;
  std::vector<Eigen::Vector2d> polygon;  ///< object frame, metres, as written in the file
  double height = 0;                     ///< metres
  std::vector<TagMount> tags;
};

/// A CM vertex / obstacle vertex pair whose signed image distance is tracked.
struct EventPair {
  std::string cvc_ray;  ///< id reported in visual_event_t.cvc_ray
  int obstacle = 0;     ///< index into ObjectModels::obstacles
  int vertex = 0;       ///< obstacle polygon vertex index
  int cm_vertex = 0;    ///< robot polygon vertex index
};

struct ObjectModels {
  ObjectModel robot;
  std::vector<ObjectModel> obstacles;
  std::vector<EventPair> events;
};

/// Loads and validates an object-model file. @throws InputError naming the file, the object (e.g.
/// "obstacles[1].tags[0].size") and what is wrong.
ObjectModels LoadObjectModels(const std::string& path);

/// The same from JSON text (`source` names it in errors).
ObjectModels ParseObjectModels(const std::string& json_text, const std::string& source);

}  // namespace visco::vision
