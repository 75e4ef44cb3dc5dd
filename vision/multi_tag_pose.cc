#include "vision/multi_tag_pose.h"

#include <visp3/core/vpHomogeneousMatrix.h>
#include <visp3/core/vpPoint.h>
#include <visp3/vision/vpPose.h>

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>

namespace visco::vision {
namespace {

using Mat6 = Eigen::Matrix<double, 6, 6>;

struct Points {
  std::vector<Eigen::Vector3d> obj;    // object frame, metres
  std::vector<Eigen::Vector2d> ideal;  // ideal (undistorted) pixels, calibration convention
};

Eigen::Vector2d IdealCorner(const CameraModel& cam, const Eigen::Vector2d& corner, double offset) {
  return cam.NormalizedToIdealPixel(cam.PixelToNormalized(corner - Eigen::Vector2d::Constant(offset)));
}

void AddTag(const CameraModel& cam, const ObjectTagObservation& t, double offset, Points& p) {
  const auto local = TagCornersInTagFrame(t.size);
  for (int k = 0; k < 4; ++k) {
    p.obj.push_back(t.oMt * local[k]);
    p.ideal.push_back(IdealCorner(cam, t.corners[k], offset));
  }
}

Points Gather(const CameraModel& cam, const std::vector<ObjectTagObservation>& tags, const std::vector<int>& use,
              double offset) {
  Points p;
  for (const int i : use) AddTag(cam, tags[i], offset, p);
  return p;
}

// Sum of squared residuals (ideal pixels) and, optionally, J^T J for a left perturbation (rotation vector, then
// translation) of cMo.
double Ssr(const CameraModel& cam, const Points& p, const Eigen::Isometry3d& cMo, Mat6* jtj) {
  double ssr = 0;
  if (jtj != nullptr) jtj->setZero();
  Eigen::Vector2d r;
  Eigen::Matrix<double, 2, 6> j;
  for (std::size_t i = 0; i < p.obj.size(); ++i) {
    if (!ReprojectPoint(cam, cMo, p.obj[i], p.ideal[i], r, jtj != nullptr ? &j : nullptr)) {
      return std::numeric_limits<double>::infinity();
    }
    ssr += r.squaredNorm();
    if (jtj != nullptr) *jtj += j.transpose() * j;
  }
  return ssr;
}

double RotationDistance(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

bool SolveOpenCv(const CameraModel& cam, const Points& p, bool sqpnp, Eigen::Isometry3d& cMo) {
  std::vector<cv::Point3d> obj;
  std::vector<cv::Point2d> img;
  for (std::size_t i = 0; i < p.obj.size(); ++i) {
    obj.emplace_back(p.obj[i].x(), p.obj[i].y(), p.obj[i].z());
    img.emplace_back(p.ideal[i].x(), p.ideal[i].y());
  }
  const cv::Matx33d k(cam.px, 0, cam.u0, 0, cam.py, cam.v0, 0, 0, 1);
  cv::Matx33d r;
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) r(a, b) = cMo.linear()(a, b);
  }
  cv::Mat rvec, tvec = (cv::Mat_<double>(3, 1) << cMo.translation().x(), cMo.translation().y(), cMo.translation().z());
  cv::Rodrigues(r, rvec);
  try {
    if (!cv::solvePnP(obj, img, k, cv::noArray(), rvec, tvec, !sqpnp,
                      sqpnp ? cv::SOLVEPNP_SQPNP : cv::SOLVEPNP_ITERATIVE)) {
      return false;
    }
  } catch (const cv::Exception&) {
    return false;
  }
  cv::Rodrigues(rvec, r);
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  for (int a = 0; a < 3; ++a) {
    for (int b = 0; b < 3; ++b) out.linear()(a, b) = r(a, b);
    out.translation()[a] = tvec.at<double>(a);
  }
  if (!out.matrix().allFinite()) return false;
  cMo = out;
  return true;
}

bool SolveVisp(const CameraModel& cam, const Points& p, Eigen::Isometry3d& cMo) {
  vpPose pose;
  for (std::size_t i = 0; i < p.obj.size(); ++i) {
    vpPoint pt(p.obj[i].x(), p.obj[i].y(), p.obj[i].z());
    pt.set_x((p.ideal[i].x() - cam.u0) / cam.px);
    pt.set_y((p.ideal[i].y() - cam.v0) / cam.py);
    pose.addPoint(pt);
  }
  vpHomogeneousMatrix m;
  for (unsigned a = 0; a < 3; ++a) {
    for (unsigned b = 0; b < 3; ++b) m[a][b] = cMo.linear()(a, b);
    m[a][3] = cMo.translation()[a];
  }
  try {
    pose.computePose(vpPose::VIRTUAL_VS, m);
  } catch (const vpException&) {
    return false;
  }
  Eigen::Isometry3d out = Eigen::Isometry3d::Identity();
  for (unsigned a = 0; a < 3; ++a) {
    for (unsigned b = 0; b < 3; ++b) out.linear()(a, b) = m[a][b];
    out.translation()[a] = m[a][3];
  }
  if (!out.matrix().allFinite()) return false;
  cMo = out;
  return true;
}

// A consistent set of tags and the pose fitted to it.
struct Candidate {
  std::vector<int> set;  // ascending
  Eigen::Isometry3d cMo;
  double rms = 0;
  int seed = -1;
  bool seed_ambiguous = false;  // singleton sets: the tag's own ambiguity flag
  bool seed_chosen = true;      // singleton sets: the tag's own chosen solution (not its alternative)
  bool coplanar = true;         // all corners of the set in one plane (within 1 mm)
};

// Whether the corners of the tags in `set` lie in one plane (to 1 mm): only then can a second, mirrored pose fit.
bool Coplanar(const std::vector<ObjectTagObservation>& tags, const std::vector<int>& set) {
  std::vector<Eigen::Vector3d> p;
  for (const int i : set) {
    for (const auto& c : TagCornersInTagFrame(tags[i].size)) p.push_back(tags[i].oMt * c);
  }
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& q : p) mean += q;
  mean /= static_cast<double>(p.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  for (const auto& q : p) cov += (q - mean) * (q - mean).transpose();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> es(cov);
  const Eigen::Vector3d normal = es.eigenvectors().col(0);
  for (const auto& q : p) {
    if (std::abs((q - mean).dot(normal)) > 1e-3) return false;
  }
  return true;
}

// Mean displacement of the tags' corners between two object poses (metres).
double CornerDistance(const std::vector<ObjectTagObservation>& tags, const Eigen::Isometry3d& a,
                      const Eigen::Isometry3d& b) {
  double sum = 0;
  int n = 0;
  for (const auto& t : tags) {
    for (const auto& c : TagCornersInTagFrame(t.size)) {
      const Eigen::Vector3d o = t.oMt * c;
      sum += (a * o - b * o).norm();
      ++n;
    }
  }
  return n > 0 ? sum / n : 0;
}

}  // namespace

double ChiSquareQuantileEven(int dof, double alpha) {
  // Survival function for even dof: Q(x) = exp(-x/2) sum_{k < dof/2} (x/2)^k / k!; bisection on it.
  auto q = [dof](double x) {
    double term = 1, sum = 1;
    for (int k = 1; k < dof / 2; ++k) sum += (term *= x / 2 / k);
    return std::exp(-x / 2) * sum;
  };
  double lo = 0, hi = 1000;
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    (q(mid) > alpha ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

double TagRmsAtObjectPose(const CameraModel& camera, const ObjectTagObservation& tag, const Eigen::Isometry3d& cMo,
                          double corner_offset_px) {
  Points p;
  AddTag(camera, tag, corner_offset_px, p);
  return std::sqrt(Ssr(camera, p, cMo, nullptr) / 4);
}

double FitObjectPose(const CameraModel& camera, const std::vector<ObjectTagObservation>& tags,
                     const std::vector<int>& use, JointPoseSolver solver, Eigen::Isometry3d& cMo,
                     double corner_offset_px) {
  const Points p = Gather(camera, tags, use, corner_offset_px);
  if (p.obj.size() < 4) return -1;
  Eigen::Isometry3d m = cMo;
  bool ok = false;
  switch (solver) {
    case JointPoseSolver::kOpenCvIterative:
      ok = SolveOpenCv(camera, p, false, m);
      break;
    case JointPoseSolver::kOpenCvSqpnp:
      ok = SolveOpenCv(camera, p, true, m);
      break;
    case JointPoseSolver::kVispVirtualVs:
      ok = SolveVisp(camera, p, m);
      break;
  }
  if (!ok) return -1;
  const double ssr = Ssr(camera, p, m, nullptr);
  if (!std::isfinite(ssr)) return -1;
  cMo = m;
  return std::sqrt(ssr / static_cast<double>(p.obj.size()));
}

std::optional<ObjectPoseFit> EstimateObjectPose(const CameraModel& camera,
                                                const std::vector<ObjectTagObservation>& tags,
                                                const PoseOptions& options, double corner_sigma_px,
                                                const std::optional<Eigen::Isometry3d>& prior_cMo,
                                                const std::optional<Eigen::Vector3d>& expected_up_c) {
  if (tags.empty()) return std::nullopt;
  const int n = static_cast<int>(tags.size());
  const double offset = options.corner_offset_px;
  ObjectPoseFit out;
  // A tag is consistent with a pose when its 4 corners' SSR is below the chi-square quantile (8 dof) times sigma^2.
  out.gate_px = std::max(std::sqrt(ChiSquareQuantileEven(8, options.tag_outlier_alpha) / 4) * corner_sigma_px,
                         options.mount_tolerance_px);
  auto consistent = [&](const std::vector<int>& set, const Eigen::Isometry3d& cMo) {
    for (const int k : set) {
      if (!(TagRmsAtObjectPose(camera, tags[k], cMo, offset) <= out.gate_px)) return false;
    }
    return true;
  };

  // Seeds: the most precise tags first (their set is usually the whole object, and later seeds in its basin are
  // skipped); a tag's other planar solution only when the tag itself could not tell them apart.
  std::vector<int> order(n);
  std::iota(order.begin(), order.end(), 0);
  std::stable_sort(order.begin(), order.end(), [&](int a, int b) {
    return tags[a].pose.unit_covariance.block<3, 3>(3, 3).trace() <
           tags[b].pose.unit_covariance.block<3, 3>(3, 3).trace();
  });
  std::vector<Candidate> cands;
  for (const int i : order) {
    const Eigen::Isometry3d tMo = tags[i].oMt.inverse();
    std::vector<std::pair<Eigen::Isometry3d, bool>> seeds{{tags[i].pose.cMo, true}};
    if (tags[i].pose.alternative && (tags[i].pose.ambiguous || n == 1)) {
      seeds.emplace_back(tags[i].pose.alternative->cMo, false);
    }
    for (const auto& [cMt, chosen] : seeds) {
      Candidate c;
      c.set = {i};
      c.cMo = cMt * tMo;
      c.rms = TagRmsAtObjectPose(camera, tags[i], c.cMo, offset);
      c.seed = i;
      c.seed_ambiguous = tags[i].pose.ambiguous;
      c.seed_chosen = chosen;
      // A seed in the basin of a pose already found (its tag agrees with it) leads to the same fit; and a set of tags
      // that are not coplanar has no second (mirror) pose: its fit is the only one for its tags.
      bool known = false;
      for (const auto& o : cands) {
        const bool has = std::find(o.set.begin(), o.set.end(), i) != o.set.end();
        known = known || (o.set.size() > 1 && has &&
                          (!o.coplanar || RotationDistance((o.cMo * tags[i].oMt).linear(), cMt.linear()) < 0.05));
      }
      if (known && n > 1) continue;
      // Grow the set: the other tags nearest the current pose first.
      std::vector<int> rest;
      for (int j = 0; j < n; ++j) {
        if (j != i) rest.push_back(j);
      }
      std::vector<double> err(n, 0);
      for (const int j : rest) err[j] = TagRmsAtObjectPose(camera, tags[j], c.cMo, offset);
      std::sort(rest.begin(), rest.end(), [&](int a, int b) { return err[a] < err[b]; });
      // All at once first (the usual case: every tag agrees); else one at a time.
      if (rest.size() > 1) {
        std::vector<int> all(n);
        std::iota(all.begin(), all.end(), 0);
        Eigen::Isometry3d m = c.cMo;
        const double rms = FitObjectPose(camera, tags, all, options.joint_solver, m, offset);
        if (rms >= 0 && consistent(all, m)) {
          c.set = all;
          c.cMo = m;
          c.rms = rms;
          rest.clear();
        }
      }
      for (const int j : rest) {
        std::vector<int> trial = c.set;
        trial.push_back(j);
        std::sort(trial.begin(), trial.end());
        Eigen::Isometry3d m = c.cMo;
        const double rms = FitObjectPose(camera, tags, trial, options.joint_solver, m, offset);
        if (rms < 0 || !consistent(trial, m)) continue;
        c.set = trial;
        c.cMo = m;
        c.rms = rms;
      }
      c.coplanar = Coplanar(tags, c.set);
      cands.push_back(c);
    }
  }

  // The largest consistent set(s); distinct poses only.
  std::size_t best_size = 0;
  for (const auto& c : cands) best_size = std::max(best_size, c.set.size());
  std::vector<Candidate> top;
  for (const auto& c : cands) {
    if (c.set.size() != best_size) continue;
    bool dup = false;
    for (auto& o : top) {
      // The same minimum reached from two seeds (to the solver's tolerance); mirrored poses differ far more.
      if (o.set == c.set && RotationDistance(o.cMo.linear(), c.cMo.linear()) < 1e-3 &&
          (o.cMo.translation() - c.cMo.translation()).norm() < 1e-4) {
        dup = true;
        if (c.rms < o.rms) o = c;
      }
    }
    if (!dup) top.push_back(c);
  }

  // Per set: the planar-ambiguity rule among its poses. The other poses stay possible while their likelihood
  // relative to the best one, exp(-dSSR / (2 sigma_c^2)), is at least joint_ambiguity_alpha (a log-likelihood-ratio
  // test on the corner noise); the clearly smaller error then wins even against the prior, so a wrong choice is not
  // carried from frame to frame once the data can tell.
  struct Choice {
    Candidate c;
    bool ambiguous = false;
    PoseDecision decided_by = PoseDecision::kUnique;
    int poses = 1;
    std::optional<PoseCandidate> other;
  };
  const double sigma2 = corner_sigma_px * corner_sigma_px;
  const double dssr_max = 2 * std::log(1 / options.joint_ambiguity_alpha) * sigma2;
  auto ssr = [](const Candidate& c) { return c.rms * c.rms * 4.0 * static_cast<double>(c.set.size()); };
  std::vector<Choice> choices;
  std::vector<bool> done(top.size(), false);
  for (std::size_t a = 0; a < top.size(); ++a) {
    if (done[a]) continue;
    std::vector<Candidate> group;
    for (std::size_t b = a; b < top.size(); ++b) {
      if (top[b].set == top[a].set) {
        group.push_back(top[b]);
        done[b] = true;
      }
    }
    Choice ch;
    ch.poses = static_cast<int>(group.size());
    if (best_size == 1) {
      // One tag: its own decision (EstimateTagPose's rule with its prior and the table normal).
      ch.c = group.front();
      for (const auto& g : group) {
        if (g.seed_chosen) ch.c = g;
      }
      ch.ambiguous = group.front().seed_ambiguous;
      ch.decided_by = PoseDecision::kSingleTag;
      ch.poses = 1;
    } else {
      std::sort(group.begin(), group.end(), [](const Candidate& x, const Candidate& y) { return x.rms < y.rms; });
      // The poses the noise cannot rule out (group[0] always).
      std::size_t possible = 1;
      while (possible < group.size() && ssr(group[possible]) - ssr(group[0]) <= dssr_max) ++possible;
      std::size_t pick = 0;
      if (group.size() > 1) ch.decided_by = PoseDecision::kSmallerError;
      if (possible > 1) {
        // Among the possible poses: the closest to the prior, else the one most "up", else the smaller error.
        ch.ambiguous = true;
        std::function<double(const Candidate&)> score;
        if (prior_cMo) {
          ch.decided_by = PoseDecision::kPrior;
          score = [&](const Candidate& c) { return RotationDistance(c.cMo.linear(), prior_cMo->linear()); };
        } else if (expected_up_c) {
          ch.decided_by = PoseDecision::kExpectedUp;
          score = [&](const Candidate& c) { return -c.cMo.linear().col(2).dot(expected_up_c->normalized()); };
        } else {
          ch.decided_by = PoseDecision::kUndecided;
        }
        for (std::size_t k = 1; score && k < possible; ++k) {
          if (score(group[k]) < score(group[pick])) pick = k;
        }
      }
      ch.c = group[pick];
      const std::size_t other = pick == 0 ? 1 : 0;
      if (group.size() > 1) ch.other = PoseCandidate{group[other].cMo, group[other].rms};
    }
    choices.push_back(ch);
  }
  if (choices.empty()) return std::nullopt;

  // Unit covariance of a fit over a set.
  auto unit_cov = [&](const std::vector<int>& set, const Eigen::Isometry3d& cMo) {
    Mat6 jtj;
    Ssr(camera, Gather(camera, tags, set, offset), cMo, &jtj);
    return Mat6(jtj.ldlt().solve(Mat6::Identity()));
  };
  // Different sets of the same size disagree: the one closest to the previous pose, else the most precise.
  std::size_t chosen = 0;
  if (choices.size() > 1) {
    double best = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < choices.size(); ++k) {
      const double score = prior_cMo ? CornerDistance(tags, choices[k].c.cMo, *prior_cMo)
                                     : unit_cov(choices[k].c.set, choices[k].c.cMo).block<3, 3>(3, 3).trace();
      if (score < best) {
        best = score;
        chosen = k;
      }
    }
  }
  const Choice& ch = choices[chosen];
  out.cMo = ch.c.cMo;
  Eigen::Quaterniond q(out.cMo.linear());
  out.cMo.linear() = q.normalized().toRotationMatrix();
  out.ambiguous = ch.ambiguous;
  out.decided_by = ch.decided_by;
  out.candidate_poses = ch.poses;
  out.alternative = ch.other;
  out.reference = ch.c.seed;
  out.inliers = ch.c.set;
  for (int k = 0; k < n; ++k) {
    if (std::find(out.inliers.begin(), out.inliers.end(), k) == out.inliers.end()) out.outliers.push_back(k);
    out.tag_rms_px.push_back(TagRmsAtObjectPose(camera, tags[k], out.cMo, offset));
  }
  Mat6 jtj;
  const Points p = Gather(camera, tags, out.inliers, offset);
  out.rms_error_px = std::sqrt(Ssr(camera, p, out.cMo, &jtj) / static_cast<double>(p.obj.size()));
  out.unit_covariance = jtj.ldlt().solve(Mat6::Identity());
  return out;
}

const char* PoseDecisionName(PoseDecision decision) {
  switch (decision) {
    case PoseDecision::kSingleTag:
      return "single_tag";
    case PoseDecision::kUnique:
      return "unique";
    case PoseDecision::kSmallerError:
      return "smaller_error";
    case PoseDecision::kPrior:
      return "prior";
    case PoseDecision::kExpectedUp:
      return "expected_up";
    case PoseDecision::kUndecided:
      return "undecided";
  }
  return "unknown";
}

}  // namespace visco::vision
