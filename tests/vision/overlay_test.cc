// The pictures of `visco detect --overlay` and `visco track --overlay` (vision/overlay.h) checked pixel by pixel on
// rendered frames with ground truth: the marks are where the truth says (CM vertex crosses, tag borders, ids), the
// event ring is on the frame where the crossing fires and on no other, nothing is drawn away from what is drawn,
// and the commands write one picture per input frame.

#include "vision/overlay.h"

#include <gtest/gtest.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <string>
#include <vector>

#include "tests/vision/sliding_robot_world.h"
#include "vision/pipeline.h"

extern char** environ;

namespace visco::vision {
namespace {

using World = test_world::SlidingRobotWorld;
constexpr int kFrames = World::kFrames;

std::filesystem::path TempDir(const std::string& name) {
  const auto dir = std::filesystem::temp_directory_path() / (name + "_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  return dir;
}

int RunProcess(const std::vector<std::string>& args) {
  std::vector<char*> argv;
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawn(&pid, argv[0], nullptr, nullptr, argv.data(), environ) != 0) return -1;
  int status = 0;
  if (waitpid(pid, &status, 0) != pid) return -1;
  return WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status);
}

ColorImage ReadColor(const std::string& path) {
  const cv::Mat m = cv::imread(path, cv::IMREAD_COLOR);
  ColorImage out;
  if (m.empty()) return out;
  out.width = m.cols;
  out.height = m.rows;
  out.bgr.assign(m.data, m.data + m.total() * 3);
  return out;
}

bool Inside(const ColorImage& p, int u, int v) { return u >= 0 && v >= 0 && u < p.width && v < p.height; }

// Pixels of colour `c` in [u0, u1] x [v0, v1].
int Count(const ColorImage& p, const Bgr& c, int u0, int v0, int u1, int v1) {
  int n = 0;
  for (int v = v0; v <= v1; ++v) {
    for (int u = u0; u <= u1; ++u) n += Inside(p, u, v) && p.at(u, v) == c ? 1 : 0;
  }
  return n;
}

// Distance from `x` to the nearest pixel of colour `c` (searched within 4 px; 1e9 if none).
double Nearest(const ColorImage& p, const Bgr& c, const Eigen::Vector2d& x) {
  double best = 1e9;
  const int u0 = static_cast<int>(std::lround(x.x())), v0 = static_cast<int>(std::lround(x.y()));
  for (int v = v0 - 4; v <= v0 + 4; ++v) {
    for (int u = u0 - 4; u <= u0 + 4; ++u) {
      if (Inside(p, u, v) && p.at(u, v) == c) best = std::min(best, (Eigen::Vector2d(u, v) - x).norm());
    }
  }
  return best;
}

double SegmentDistance(const Eigen::Vector2d& x, const Eigen::Vector2d& a, const Eigen::Vector2d& b) {
  const Eigen::Vector2d ab = b - a;
  const double t = ab.squaredNorm() > 0 ? std::clamp((x - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0) : 0.0;
  return (a + t * ab - x).norm();
}

struct Box {
  double u0, v0, u1, v1;
  bool Contains(const Eigen::Vector2d& x) const { return x.x() >= u0 && x.x() <= u1 && x.y() >= v0 && x.y() <= v1; }
};

Box BoundsOf(const std::vector<Eigen::Vector2d>& pts, double grow) {
  Box b{1e9, 1e9, -1e9, -1e9};
  for (const auto& p : pts) {
    b.u0 = std::min(b.u0, p.x() - grow), b.v0 = std::min(b.v0, p.y() - grow);
    b.u1 = std::max(b.u1, p.x() + grow), b.v1 = std::max(b.v1, p.y() + grow);
  }
  return b;
}

// The projected corners (top and bottom) of an object's prism at its true pose.
std::vector<Eigen::Vector2d> PrismImage(const World& w, const ObjectModel& m, const Eigen::Isometry3d& wMo) {
  std::vector<Eigen::Vector2d> out;
  const Eigen::Isometry3d cMo = w.wMc.inverse() * wMo;
  for (const auto& p : m.polygon) {
    out.push_back(w.camera.ProjectIdeal(cMo * Eigen::Vector3d(p.x(), p.y(), 0)));
    out.push_back(w.camera.ProjectIdeal(cMo * Eigen::Vector3d(p.x(), p.y(), m.height)));
  }
  return out;
}

// The true tag corners in the picture's pixels (calibration convention; the camera has no distortion).
std::vector<Eigen::Vector2d> TagImage(const World& w, const TagMount& t, const Eigen::Isometry3d& wMo) {
  std::vector<Eigen::Vector2d> out;
  const Eigen::Isometry3d cMt = w.wMc.inverse() * wMo * t.oMt;
  for (const auto& c : TagCornersInTagFrame(t.size)) out.push_back(w.camera.ProjectIdeal(cMt * c));
  return out;
}

// Every edge midpoint of a quad has a pixel of colour `c` within 1 px.
void ExpectBorder(const ColorImage& p, const std::vector<Eigen::Vector2d>& quad, const Bgr& c,
                  const std::string& what) {
  for (std::size_t k = 0; k < quad.size(); ++k) {
    const Eigen::Vector2d mid = (quad[k] + quad[(k + 1) % quad.size()]) / 2;
    EXPECT_LE(Nearest(p, c, mid), 1.0) << what << " edge " << k << " at " << mid.transpose();
  }
}

// The id text sits above the top-left of the tag's bounding box.
void ExpectIdText(const ColorImage& p, const std::vector<Eigen::Vector2d>& quad, const std::string& what) {
  const Box b = BoundsOf(quad, 0);
  const int n = Count(p, overlay_color::kTagId, static_cast<int>(b.u0) - 2, static_cast<int>(b.v0) - 16,
                      static_cast<int>(b.u0) + 40, static_cast<int>(b.v0) - 1);
  EXPECT_GE(n, 15) << what << ": no id text above the tag's top-left";
}

// The changed pixels of `pic` against the grey `input` that `allowed` does not explain (prints a few).
int Unexplained(const ColorImage& pic, const GrayImage& input,
                const std::function<bool(const Eigen::Vector2d&)>& allowed, int* changed) {
  int bad = 0;
  *changed = 0;
  for (int v = 0; v < pic.height; ++v) {
    for (int u = 0; u < pic.width; ++u) {
      const std::uint8_t g = input.at(u, v);
      if (pic.at(u, v) == Bgr{g, g, g}) continue;
      ++*changed;
      if (allowed({u, v})) continue;
      if (bad++ < 5) ADD_FAILURE() << "pixel (" << u << ", " << v << ") drawn where nothing should be";
    }
  }
  return bad;
}

TEST(Overlay, TrackPicturesAgainstTruth) {
  const World w;
  PipelineOptions po;
  po.detector.quad_sigma = 0.8f;
  VisionPipeline pipeline(w.camera, w.wMc, w.models, po);
  TrackOverlay overlay(w.camera, w.wMc, w.models);
  int reported = -1, event_frames = 0;
  for (int i = 0; i < kFrames; ++i) {
    SCOPED_TRACE("frame " + std::to_string(i));
    Frame frame;
    frame.seq = i;
    frame.utime = 1'000'000 + i * 33'333;
    frame.image = w.Render(i);
    const PipelineOutput out = pipeline.Process(frame, frame.utime);
    ASSERT_TRUE(out.processed);
    const FrameFeatures& f = pipeline.features().last();
    ASSERT_TRUE(f.robot.valid);
    const ColorImage pic = overlay.Draw(frame, out, f);
    ASSERT_EQ(pic.width, 640);
    ASSERT_EQ(pic.height, 480);
    const Eigen::Isometry3d wMr = w.Robot(i);
    const Eigen::Isometry3d cMr = w.wMc.inverse() * wMr;

    // CM vertices: a magenta cross at the projected truth (within 1 px).
    std::vector<Eigen::Vector2d> cm_truth;
    for (const auto& p : w.models.robot.polygon) {
      const Eigen::Vector2d t = w.camera.ProjectIdeal(cMr * Eigen::Vector3d(p.x(), p.y(), w.models.robot.height));
      cm_truth.push_back(t);
      // Its centre and the four arms (a cross moved along one arm still covers the centre, not the other arm).
      EXPECT_LE(Nearest(pic, overlay_color::kCmVertex, t), 1.0) << "CM vertex at " << t.transpose();
      for (const Eigen::Vector2d& d :
           {Eigen::Vector2d(1, 0), Eigen::Vector2d(-1, 0), Eigen::Vector2d(0, 1), Eigen::Vector2d(0, -1)}) {
        EXPECT_LE(Nearest(pic, overlay_color::kCmVertex, t + (OverlayMarks::kCmCrossHalf - 1) * d), 1.0)
            << "CM vertex cross arm " << d.transpose() << " at " << t.transpose();
      }
    }
    // Tags: green borders on the true edges, red ids above them.
    const auto robot_tag = TagImage(w, w.models.robot.tags[0], wMr);
    const auto block_tag = TagImage(w, w.models.obstacles[0].tags[0], w.wMo);
    ExpectBorder(pic, robot_tag, overlay_color::kTag, "robot tag");
    ExpectBorder(pic, block_tag, overlay_color::kTag, "block tag");
    ExpectIdText(pic, robot_tag, "robot tag");
    ExpectIdText(pic, block_tag, "block tag");

    // Events: the ring around the pair's CM vertex in the frame where it fires, no event colour anywhere else.
    bool fired = false;
    for (std::size_t k = 0; k < f.pairs.size(); ++k) {
      if (!f.pairs[k].crossed) continue;
      fired = true;
      if (w.models.events[k].cvc_ray == "block.v0.cm1" && reported < 0) reported = i;
      const Eigen::Vector2d c = cm_truth[static_cast<std::size_t>(w.models.events[k].cm_vertex)];
      int on_ring = 0;
      for (int a = 0; a < 32; ++a) {
        const Eigen::Vector2d x =
            c + OverlayMarks::kEventRadius * Eigen::Vector2d(std::cos(a * M_PI / 16), std::sin(a * M_PI / 16));
        on_ring += Nearest(pic, overlay_color::kEvent, x) <= 1.5 ? 1 : 0;
      }
      EXPECT_GE(on_ring, 28) << w.models.events[k].cvc_ray << ": no event ring";
    }
    if (fired) {
      ++event_frames;
    } else {
      EXPECT_EQ(Count(pic, overlay_color::kEvent, 0, 0, pic.width - 1, pic.height - 1), 0) << "event mark, no event";
    }

    // Nothing drawn away from the marks: each changed pixel is in the status lines, on a VC line, near an object
    // (borders, ids, prisms, crosses, labels), on a searched window's outline, on a distance segment, or on the
    // event's label.
    const int status_rows = 2 + static_cast<int>(f.pairs.size());
    const Box robot_box = BoundsOf(PrismImage(w, w.models.robot, wMr), 40);
    Box block_box = BoundsOf(PrismImage(w, w.models.obstacles[0], w.wMo), 40);
    block_box.u1 += 40;  // the VC lines' labels "block.v<j>" right of the edges' tops
    const Eigen::Isometry3d cMo = w.wMc.inverse() * w.wMo;
    std::vector<Eigen::Vector3d> vc_lines;
    for (const auto& e : w.models.events) {
      const auto& v = w.models.obstacles[0].polygon[static_cast<std::size_t>(e.vertex)];
      const Eigen::Vector2d b = w.camera.ProjectIdeal(cMo * Eigen::Vector3d(v.x(), v.y(), 0));
      const Eigen::Vector2d t =
          w.camera.ProjectIdeal(cMo * Eigen::Vector3d(v.x(), v.y(), w.models.obstacles[0].height));
      Eigen::Vector3d l = Eigen::Vector3d(b.x(), b.y(), 1).cross(Eigen::Vector3d(t.x(), t.y(), 1));
      vc_lines.push_back(l / l.head<2>().norm());
    }
    auto allowed = [&](const Eigen::Vector2d& x) {
      if (x.y() <= status_rows * 13 + 5) return true;
      if (robot_box.Contains(x) || block_box.Contains(x)) return true;
      for (const auto& l : vc_lines) {
        if (std::abs(l.head<2>().dot(x) + l.z()) <= 2.5) return true;
        for (const auto& c : cm_truth) {
          if (SegmentDistance(x, c, c - (l.head<2>().dot(c) + l.z()) * l.head<2>()) <= 2.5) return true;
        }
      }
      for (const RoiWindow& r : out.roi_windows) {
        const bool in = x.x() >= r.x0 - 1 && x.x() <= r.x1 && x.y() >= r.y0 - 1 && x.y() <= r.y1;
        const bool deep = x.x() >= r.x0 + 1 && x.x() <= r.x1 - 2 && x.y() >= r.y0 + 1 && x.y() <= r.y1 - 2;
        if (in && !deep) return true;
      }
      for (const auto& c : cm_truth) {
        if (fired && x.x() >= c.x() + 12 && x.x() <= c.x() + 260 && x.y() >= c.y() - 32 && x.y() <= c.y() - 8) {
          return true;
        }
      }
      return false;
    };
    int changed = 0;
    EXPECT_EQ(Unexplained(pic, frame.image, allowed, &changed), 0);
    EXPECT_GT(changed, 1000);
    EXPECT_LT(changed, pic.width * pic.height / 4);
  }
  const int truth = w.TrueCrossing();
  std::printf("crossing of block.v0.cm1 reported at frame %d (truth %d), %d frame(s) with an event ring\n", reported,
              truth, event_frames);
  ASSERT_GT(truth, 0);
  EXPECT_GE(reported, truth - 1);
  EXPECT_LE(reported, truth + 3);
}

TEST(Overlay, MarksFollowTheLensDistortion) {
  // Barrel distortion (OpenCV's k1 = -0.3): the features live in ideal pixels, the picture in observed ones.
  World w;
  w.camera.distortion = DistortionModel::kOpenCV;
  w.camera.dist = {-0.3, 0, 0, 0};
  PipelineOptions po;
  po.detector.quad_sigma = 0.8f;
  VisionPipeline pipeline(w.camera, w.wMc, w.models, po);
  TrackOverlay overlay(w.camera, w.wMc, w.models);
  double largest_shift = 0;
  for (int i = 0; i < kFrames; i += 4) {
    SCOPED_TRACE("frame " + std::to_string(i));
    Frame frame;
    frame.seq = i;
    frame.utime = 1'000'000 + i * 33'333;
    frame.image = w.Render(i);
    const PipelineOutput out = pipeline.Process(frame, frame.utime);
    ASSERT_TRUE(pipeline.features().last().robot.valid);
    const ColorImage pic = overlay.Draw(frame, out, pipeline.features().last());
    const Eigen::Isometry3d cMr = w.wMc.inverse() * w.Robot(i);
    for (const auto& p : w.models.robot.polygon) {
      const Eigen::Vector3d top = cMr * Eigen::Vector3d(p.x(), p.y(), w.models.robot.height);
      const Eigen::Vector2d t = w.camera.Project(top);
      largest_shift = std::max(largest_shift, (t - w.camera.ProjectIdeal(top)).norm());
      EXPECT_LE(Nearest(pic, overlay_color::kCmVertex, t), 1.0) << "CM vertex at " << t.transpose();
      for (const Eigen::Vector2d& d :
           {Eigen::Vector2d(1, 0), Eigen::Vector2d(-1, 0), Eigen::Vector2d(0, 1), Eigen::Vector2d(0, -1)}) {
        EXPECT_LE(Nearest(pic, overlay_color::kCmVertex, t + (OverlayMarks::kCmCrossHalf - 1) * d), 1.0)
            << "CM vertex cross arm " << d.transpose() << " at " << t.transpose();
      }
    }
    // The VC line of the block's vertex 0 is straight in ideal pixels and bent in the picture.
    const Eigen::Isometry3d cMo = w.wMc.inverse() * w.wMo;
    const auto& v0 = w.models.obstacles[0].polygon[0];
    const Eigen::Vector2d b = w.camera.ProjectIdeal(cMo * Eigen::Vector3d(v0.x(), v0.y(), 0));
    const Eigen::Vector2d a =
        w.camera.ProjectIdeal(cMo * Eigen::Vector3d(v0.x(), v0.y(), w.models.obstacles[0].height));
    for (const double v : {380.0, 450.0}) {
      const Eigen::Vector2d ideal(a.x() + (b.x() - a.x()) * (v - a.y()) / (b.y() - a.y()), v);
      const Eigen::Vector2d seen = w.camera.NormalizedToPixel(
          {(ideal.x() - w.camera.u0) / w.camera.px, (ideal.y() - w.camera.v0) / w.camera.py});
      largest_shift = std::max(largest_shift, (seen - ideal).norm());
      EXPECT_LE(Nearest(pic, overlay_color::kVcLine, seen), 1.5) << "VC line at " << seen.transpose();
    }
  }
  std::printf("lens distortion moves the checked marks by up to %.1f px\n", largest_shift);
  EXPECT_GT(largest_shift, 3.0);  // the test would fail if the marks were drawn in ideal pixels
}

TEST(Overlay, LostTagsAndFaultsAreMarked) {
  const World w;
  PipelineOptions po;
  po.detector.quad_sigma = 0.8f;
  VisionPipeline pipeline(w.camera, w.wMc, w.models, po);
  TrackOverlay overlay(w.camera, w.wMc, w.models);
  auto draw = [&](int i, std::int64_t seq, bool robot_tag, PipelineOutput& out, GrayImage& image) {
    Frame frame;
    frame.seq = seq;
    frame.utime = 1'000'000 + seq * 33'333;
    frame.image = w.Render(i, robot_tag);
    image = frame.image;
    out = pipeline.Process(frame, frame.utime);
    return overlay.Draw(frame, out, pipeline.features().last());
  };
  auto grey = [](const ColorImage& p, const GrayImage& in, int u, int v) {
    return p.at(u, v) == Bgr{in.at(u, v), in.at(u, v), in.at(u, v)};
  };
  PipelineOutput out;
  GrayImage image;
  for (int i = 0; i < 3; ++i) {
    const ColorImage p = draw(i, i, true, out, image);
    EXPECT_TRUE(grey(p, image, 1, 240)) << "frame " << i << ": a fault border without a fault";
  }
  // Frame 3: the robot's tag is not seen. An X over where it was in frame 2 (its diagonals cross at the tag's
  // centre), "robot not seen", the robot-lost fault with the red border.
  ColorImage p = draw(3, 3, false, out, image);
  ASSERT_EQ(out.lost_tags, std::vector<int>{0});
  const auto last = TagImage(w, w.models.robot.tags[0], w.Robot(2));
  EXPECT_LE(Nearest(p, overlay_color::kLost, (last[0] + last[2]) / 2), 1.0) << "no X at the lost tag";
  EXPECT_LE(Nearest(p, overlay_color::kLost, (3 * last[0] + last[2]) / 4), 1.5) << "no X along the diagonal";
  EXPECT_EQ(Count(p, overlay_color::kCmVertex, 0, 0, p.width - 1, p.height - 1), 0) << "CM vertices of no robot";
  EXPECT_EQ(p.at(1, 240), overlay_color::kFault);
  EXPECT_GT(Count(p, overlay_color::kFault, 4, p.height - 18, 300, p.height - 4), 50) << "no fault text";
  // Frames 4 and 5 lost on the way (seq 6 follows seq 3): the gap is a fault of this picture; the robot seen again
  // is a cleared fault (green text at the bottom).
  p = draw(4, 6, true, out, image);
  EXPECT_EQ(p.at(1, 240), overlay_color::kFault);
  EXPECT_GT(Count(p, overlay_color::kCleared, 4, p.height - 48, 300, p.height - 4), 50) << "no cleared fault";
  // Then a good frame: no border.
  p = draw(5, 7, true, out, image);
  EXPECT_TRUE(out.faults.empty());
  EXPECT_TRUE(grey(p, image, 1, 240));
}

TEST(Overlay, DetectCommandPicture) {
  const World w;
  const auto dir = TempDir("visco_overlay_detect");
  const GrayImage image = w.Render(0);
  const std::string in = (dir / "frame.png").string(), pic_path = (dir / "overlay.png").string();
  WriteGrayImage(image.view(), in);
  ASSERT_EQ(RunProcess({VISCO_BIN, "detect", in, "--camera", "data/vision/synthetic_camera.xml", "--tag-size", "0.06",
                        "--out", (dir / "detect.json").string(), "--overlay", pic_path}),
            0);
  const ColorImage pic = ReadColor(pic_path);
  ASSERT_EQ(pic.width, 640);
  ASSERT_EQ(pic.height, 480);
  const auto robot_tag = TagImage(w, w.models.robot.tags[0], w.Robot(0));
  const auto block_tag = TagImage(w, w.models.obstacles[0].tags[0], w.wMo);
  ExpectBorder(pic, robot_tag, overlay_color::kTag, "robot tag");
  ExpectBorder(pic, block_tag, overlay_color::kTag, "block tag");
  ExpectIdText(pic, robot_tag, "robot tag");
  ExpectIdText(pic, block_tag, "block tag");
  // Corner 0 (AprilTag order) carries a cross.
  EXPECT_GE(
      Count(pic, overlay_color::kTag, static_cast<int>(robot_tag[0].x()) - 5, static_cast<int>(robot_tag[0].y()) - 5,
            static_cast<int>(robot_tag[0].x()) + 5, static_cast<int>(robot_tag[0].y()) + 5),
      12);
  // Nothing but the header line away from the tags (ids, frames and borders stay within 40 px of the tag).
  const Box rb = BoundsOf(robot_tag, 40), bb = BoundsOf(block_tag, 40);
  int changed = 0;
  EXPECT_EQ(Unexplained(
                pic, image, [&](const Eigen::Vector2d& x) { return x.y() <= 18 || rb.Contains(x) || bb.Contains(x); },
                &changed),
            0);
  EXPECT_GT(changed, 200);
  std::filesystem::remove_all(dir);
}

TEST(Overlay, TrackCommandOnePicturePerFrame) {
  const World w;
  const auto dir = TempDir("visco_overlay_track");
  const auto frames = dir / "frames";
  std::filesystem::create_directories(frames);
  for (int i = 0; i < kFrames; ++i) {
    char name[32];
    std::snprintf(name, sizeof name, "f%02d.png", i);
    WriteGrayImage(w.Render(i).view(), (frames / name).string());
  }
  std::ofstream(frames / "f05b.png") << "not a picture";  // a bad frame between frames 5 and 6
  const int pulls = kFrames + 1;
  const std::vector<std::string> base = {VISCO_BIN,      "track",
                                         "--camera",     "data/vision/synthetic_camera.xml",
                                         "--extrinsics", "data/vision/demo_extrinsics.json",
                                         "--objects",    "data/vision/demo_objects.json",
                                         "--quad-sigma", "0.8",
                                         "--no-publish", "--images",
                                         frames.string()};
  auto with = [&](std::vector<std::string> extra) {
    std::vector<std::string> a = base;
    a.insert(a.end(), extra.begin(), extra.end());
    return a;
  };
  const auto folder = dir / "pictures";
  const std::string json = (dir / "out.jsonl").string();
  ASSERT_EQ(RunProcess(with({"--overlay", folder.string(), "--out", json})), 0);
  // The JSON lines: the picture index of each pull, and where block.v0.cm1 fired.
  std::vector<nlohmann::json> lines;
  {
    std::ifstream f(json);
    std::string l;
    while (std::getline(f, l)) lines.push_back(nlohmann::json::parse(l));
  }
  ASSERT_FALSE(lines.empty());
  EXPECT_EQ(lines.back().at("summary").at("overlay_frames"), pulls);
  int index = 0, fired = -1;
  for (const auto& l : lines) {
    if (l.contains("seq")) {
      for (const auto& e : l.at("events")) {
        const bool crossed = e.at("crossed").is_boolean() ? e.at("crossed").get<bool>() : e.at("crossed") != 0;
        if (e.at("cvc_ray") == "block.v0.cm1" && crossed && fired < 0) fired = index;
      }
      ++index;
    } else if (l.contains("fault")) {
      ++index;  // the bad frame: a picture of its own
    }
  }
  EXPECT_EQ(index, pulls);
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(folder)) files.push_back(e.path().filename().string());
  std::sort(files.begin(), files.end());
  ASSERT_EQ(static_cast<int>(files.size()), pulls);
  EXPECT_EQ(files.front(), "000000.png");
  EXPECT_EQ(files.back(), "000024.png");
  // The bad frame (the 7th pull): black, framed in red.
  const ColorImage bad = ReadColor((folder / "000006.png").string());
  ASSERT_EQ(bad.width, 640);
  EXPECT_EQ(bad.at(1, 240), overlay_color::kFault);
  EXPECT_EQ(bad.at(320, 240), (Bgr{0, 0, 0}));
  // The event ring on the picture of the frame where the crossing fired, not on the one before or after.
  ASSERT_GT(fired, 7);
  auto event_pixels = [&](int k) {
    char name[32];
    std::snprintf(name, sizeof name, "%06d.png", k);
    const ColorImage p = ReadColor((folder / name).string());
    return Count(p, overlay_color::kEvent, 0, 0, p.width - 1, p.height - 1);
  };
  EXPECT_GT(event_pixels(fired), 100);
  EXPECT_EQ(event_pixels(fired - 1), 0);
  EXPECT_EQ(event_pixels(fired + 1), 0);
  // The same as a video: one frame per pull.
  const std::string video = (dir / "overlay.avi").string();
  ASSERT_EQ(RunProcess(with({"--overlay", video, "--out", json})), 0);
  cv::VideoCapture cap(video);
  ASSERT_TRUE(cap.isOpened());
  int read = 0;
  for (cv::Mat m; cap.read(m);) {
    EXPECT_EQ(m.cols, 640);
    ++read;
  }
  EXPECT_EQ(read, pulls);
  std::printf("track --overlay: %d pictures (%d frames + 1 bad), block.v0.cm1 fired on picture %d\n", pulls, kFrames,
              fired);
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace visco::vision
