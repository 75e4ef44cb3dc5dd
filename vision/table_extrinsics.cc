#include "vision/table_extrinsics.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <nlohmann/json.hpp>

#include "common/error.h"

namespace visco::vision {
namespace {

Eigen::Matrix3d CrossMatrix(const Eigen::Vector3d& a) {
  Eigen::Matrix3d m;
  m << 0, -a.z(), a.y(), a.z(), 0, -a.x(), -a.y(), a.x(), 0;
  return m;
}

Eigen::Vector3d RotationVector(const Eigen::Matrix3d& r) {
  const Eigen::AngleAxisd aa(r);
  return aa.angle() * aa.axis();
}

Eigen::Matrix3d RotationFromVector(const Eigen::Vector3d& w) {
  const double angle = w.norm();
  if (angle < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, w / angle).toRotationMatrix();
}

// The world-frame perturbation [w, v] taking `from` to `to` (R_to = Exp(w) R_from, t_to = t_from + v).
Eigen::Matrix<double, 6, 1> Difference(const Eigen::Isometry3d& to, const Eigen::Isometry3d& from) {
  Eigen::Matrix<double, 6, 1> d;
  d.head<3>() = RotationVector(to.linear() * from.linear().transpose());
  d.tail<3>() = to.translation() - from.translation();
  return d;
}

}  // namespace

PoseCovariance6 WorldCovarianceFromTagCovariance(const Eigen::Isometry3d& wMc, const Eigen::Isometry3d& cMt,
                                                 const PoseCovariance6& tag_covariance) {
  const Eigen::Matrix3d r_wc = wMc.linear();
  PoseCovariance6 j = PoseCovariance6::Zero();
  j.block<3, 3>(0, 0) = -r_wc;
  j.block<3, 3>(3, 0) = -r_wc * CrossMatrix(cMt.translation());
  j.block<3, 3>(3, 3) = -r_wc;
  return j * tag_covariance * j.transpose();
}

std::optional<TableTagView> ObserveTableTag(TagDetector& detector, const GrayImageView& image,
                                            const CameraModel& camera, const TableTag& tag,
                                            const PoseOptions& pose_options,
                                            const std::optional<Eigen::Isometry3d>& prior_cMt) {
  for (const TagObservation& o : detector.Detect(image)) {
    if (o.id != tag.id || o.family != tag.family) continue;
    // The table's normal in the camera frame is unknown before calibration; the prior (an earlier frame) decides.
    const std::optional<TagPose> pose = EstimateTagPose(camera, o.corners, tag.size, pose_options, prior_cMt);
    if (!pose) return std::nullopt;
    TableTagView v;
    v.pose = *pose;
    v.wMc = ExtrinsicsFromTableTag(tag.wMt, pose->cMo);
    v.unit_covariance = WorldCovarianceFromTagCovariance(v.wMc, pose->cMo, pose->unit_covariance);
    return v;
  }
  return std::nullopt;
}

TableExtrinsics CombineTableTagViews(const std::vector<TableTagView>& views, const TableTag& tag) {
  if (views.empty()) throw JobFailed("no frame showed the table tag");
  TableExtrinsics out;
  const double n = static_cast<double>(views.size());
  out.frames = static_cast<int>(views.size());
  // Mean pose: rotation by Gauss-Newton on the rotation vectors about the current mean (a few steps converge for
  // poses this close together), translation the plain mean.
  Eigen::Isometry3d mean = views.front().wMc;
  for (int iteration = 0; iteration < 5; ++iteration) {
    Eigen::Vector3d w = Eigen::Vector3d::Zero();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    for (const auto& v : views) {
      w += RotationVector(v.wMc.linear() * mean.linear().transpose());
      t += v.wMc.translation();
    }
    mean.linear() = RotationFromVector(w / n) * mean.linear();
    mean.translation() = t / n;
  }
  out.wMc = mean;
  PoseCovariance6 unit = PoseCovariance6::Zero();
  double ssr = 0;
  for (const auto& v : views) {
    const Eigen::Matrix<double, 6, 1> d = Difference(v.wMc, mean);
    out.spread += d * d.transpose();
    unit += v.unit_covariance;
    ssr += 4 * v.pose.rms_error_px * v.pose.rms_error_px;
    out.mean_rms_px += v.pose.rms_error_px / n;
    out.max_rms_px = std::max(out.max_rms_px, v.pose.rms_error_px);
    out.ambiguous_frames += v.pose.ambiguous ? 1 : 0;
  }
  if (views.size() > 1) out.spread /= n - 1;
  unit /= n;
  out.corner_sigma_px = std::sqrt(ssr / (2 * n));
  out.reprojection = unit * out.corner_sigma_px * out.corner_sigma_px;
  // The tag placed with error [w, v] (world frame) moves the camera as the tag: R' = Exp(w) R, and the camera centre
  // turns about the tag's origin: t' = t + v + w x (t_wc - t_wt).
  PoseCovariance6 tag_cov = PoseCovariance6::Zero();
  tag_cov.diagonal().head<3>().setConstant(tag.rotation_stddev_rad * tag.rotation_stddev_rad);
  tag_cov.diagonal().tail<3>().setConstant(tag.position_stddev_m * tag.position_stddev_m);
  PoseCovariance6 j = PoseCovariance6::Identity();
  j.block<3, 3>(3, 0) = -CrossMatrix(mean.translation() - tag.wMt.translation());
  out.placement = j * tag_cov * j.transpose();
  out.covariance = out.spread / n + out.reprojection + out.placement;
  return out;
}

void SaveExtrinsicsWithStddev(const Eigen::Isometry3d& wMc, const PoseCovariance6& covariance,
                              const std::string& camera_name, const std::string& path) {
  nlohmann::ordered_json j;
  if (!camera_name.empty()) j["camera"] = camera_name;
  const Eigen::Vector3d t = wMc.translation();
  const Eigen::Matrix3d r = wMc.rotation();
  j["wMc"]["t"] = {t.x(), t.y(), t.z()};
  j["wMc"]["R"] = {{r(0, 0), r(0, 1), r(0, 2)}, {r(1, 0), r(1, 1), r(1, 2)}, {r(2, 0), r(2, 1), r(2, 2)}};
  const Eigen::Matrix<double, 6, 1> sd = covariance.diagonal().cwiseMax(0.0).cwiseSqrt();
  j["wMc"]["stddev"]["position_m"] = {sd[3], sd[4], sd[5]};
  j["wMc"]["stddev"]["rotation_deg"] = {sd[0] * 180 / M_PI, sd[1] * 180 / M_PI, sd[2] * 180 / M_PI};
  std::ofstream out(path);
  if (!out) throw JobFailed("cannot write extrinsics " + path);
  out << j.dump(2) << "\n";
  if (!out) throw JobFailed("cannot write extrinsics " + path);
}

}  // namespace visco::vision
