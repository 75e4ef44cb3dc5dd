// The pipeline end to end on rendered frames: an image folder with a corrupt and a wrongly sized file, frames out of
// order, the robot lost and found again, image_t decoding and the LCM camera channel, outputs on a real LCM bus
// (memq) and in the LatestValue hand-off.

#include "vision/pipeline.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <lcm/lcm-cpp.hpp>
#include <map>
#include <mutex>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/videoio.hpp>
#include <thread>

#include "lcmtypes/channels.h"
#include "tests/vision/demo_world.h"
#include "tests/vision/sanitized_count.h"
#include "vision/camera.h"
#include "vision/object_model.h"
#include "vision/pipeline_config.h"
#include "vision/tag_renderer.h"

namespace visco::vision {
namespace {

const CameraModel& kCam = test_world::kDemoCamera;

using test_world::Planar;

struct World {
  ObjectModels models = LoadObjectModels("data/vision/demo_objects.json");
  Eigen::Isometry3d wMc = LoadExtrinsics("data/vision/demo_extrinsics.json");
  static Eigen::Isometry3d Robot(int i) { return Planar(-0.16 + 0.012 * i, 0.0, 0.1); }
  GrayImage Render(int i, bool with_robot = true) const { return RenderAt(Robot(i), 77 + i, with_robot); }
  GrayImage RenderAt(const Eigen::Isometry3d& wMr, std::uint32_t seed, bool with_robot = true) const {
    RenderScene scene;
    scene.polygons.push_back({{{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}}, 120});
    const Eigen::Isometry3d wMo = Planar(0.02, 0.12, 0.3);
    if (with_robot) {
      AddPrism(scene, models.robot.polygon, models.robot.height, wMr, 70, 60);
      scene.tags.push_back({"tag36h11", 0, models.robot.tags[0].size, wMr * models.robot.tags[0].oMt});
    }
    AddPrism(scene, models.obstacles[0].polygon, models.obstacles[0].height, wMo, 160, 140);
    scene.tags.push_back({"tag36h11", 1, models.obstacles[0].tags[0].size, wMo * models.obstacles[0].tags[0].oMt});
    RenderOptions ro;
    ro.noise_stddev = 1;
    ro.seed = seed;
    return visco::vision::Render(kCam, wMc, scene, ro);
  }
};

template <typename T>
struct Collector {
  std::vector<T> got;
  void Handle(const lcm::ReceiveBuffer*, const std::string&, const T* m) { got.push_back(*m); }
};

PipelineOptions Options() {
  PipelineOptions o;
  o.detector.quad_sigma = 0.8f;
  return o;
}

// `visco track` / `replay`: the extrinsics file's optional `wMc.stddev` reaches the feature estimator's noise model;
// without it the extrinsics are exact (zero covariance), as before.
TEST(PipelineConfig, ExtrinsicsStddevReachesTheNoiseModel) {
  PipelineConfig c;
  c.camera = "data/vision/synthetic_camera.xml";
  c.objects = "data/vision/demo_objects.json";
  c.extrinsics = "data/vision/demo_extrinsics.json";
  const LoadedPipeline exact = LoadPipelineConfig(c);
  EXPECT_EQ(exact.options.noise.extrinsics_covariance, PoseCovariance::Zero());
  const std::string path = (std::filesystem::temp_directory_path() / "visco_pipeline_extrinsics_sd.json").string();
  std::ofstream(path) << R"({"wMc": {"t": [0.0, -0.45, 0.5], "rpy_deg": [-132, 0, 0],
                                     "stddev": {"position_m": 0.001, "rotation_deg": [0.1, 0.2, 0.3]}}})";
  c.extrinsics = path;
  const LoadedPipeline loaded = LoadPipelineConfig(c);
  EXPECT_TRUE(loaded.wMc.isApprox(exact.wMc, 1e-12));
  const double k = M_PI / 180;
  Eigen::Matrix<double, 6, 1> diag;
  diag << std::pow(0.1 * k, 2), std::pow(0.2 * k, 2), std::pow(0.3 * k, 2), 1e-6, 1e-6, 1e-6;
  EXPECT_TRUE(loaded.options.noise.extrinsics_covariance.isApprox(PoseCovariance(diag.asDiagonal()), 1e-12));
  std::filesystem::remove(path);
}

TEST(Pipeline, FolderWithBadFilesToLcmAndLatestValue) {
  const World w;
  const auto dir = std::filesystem::temp_directory_path() / ("visco_pipeline_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const int n = 12;
  for (int i = 0; i < n; ++i) {
    char name[32];
    std::snprintf(name, sizeof(name), "frame_%04d.png", i);
    WriteGrayImage(w.Render(i).view(), (dir / name).string());
  }
  std::ofstream(dir / "frame_0005b.png") << "this is not a PNG";
  WriteGrayImage(GrayImage(320, 240, 100).view(), (dir / "frame_0007b.png").string());

  lcm::LCM bus("memq://");
  ASSERT_TRUE(bus.good());
  Collector<visco::fault_t> faults;
  Collector<visco::robot_estimate_t> robots;
  Collector<visco::visual_events_t> events;
  Collector<visco::tag_detections_t> detections;
  bus.subscribe(channels::kFault, &Collector<visco::fault_t>::Handle, &faults);
  bus.subscribe(channels::kRobotEstimate, &Collector<visco::robot_estimate_t>::Handle, &robots);
  bus.subscribe(channels::kVisualEvents, &Collector<visco::visual_events_t>::Handle, &events);
  bus.subscribe(channels::kTagDetections, &Collector<visco::tag_detections_t>::Handle, &detections);
  LatestValue<VisionSnapshot> latest;
  VisionPipeline pipeline(kCam, w.wMc, w.models, Options());
  PipelineThread thread(MakeFolderSource(dir.string(), 30, 1'000'000), pipeline, &bus, &latest);
  thread.Start();
  thread.Join();
  while (bus.handleTimeout(0) > 0) {
  }
  EXPECT_EQ(thread.frames(), n);
  EXPECT_EQ(thread.bad_frames(), 2);
  ASSERT_EQ(faults.got.size(), 2u);
  EXPECT_NE(faults.got[0].message.find("frame_0005b.png"), std::string::npos) << faults.got[0].message;
  EXPECT_NE(faults.got[0].message.find("cannot decode"), std::string::npos);
  EXPECT_NE(faults.got[1].message.find("320x240"), std::string::npos) << faults.got[1].message;
  EXPECT_EQ(faults.got[1].code, visco::fault_t::CODE_BAD_MESSAGE);
  EXPECT_GT(faults.got[1].utime, 0);
  ASSERT_EQ(robots.got.size(), static_cast<std::size_t>(n));
  ASSERT_EQ(events.got.size(), static_cast<std::size_t>(n));
  ASSERT_EQ(detections.got.size(), static_cast<std::size_t>(n));
  // Every good file's robot estimate against the truth of its frame (the two bad files take no frame number of the
  // sequence: frame_0005b.png is the 7th file, so seq counts files and the rendered index is recovered from it).
  double worst = 0;
  for (std::size_t k = 0; k < robots.got.size(); ++k) {
    const auto& r = robots.got[k];
    EXPECT_TRUE(r.valid);
    const std::int64_t file = r.frame_seq;
    const int index = static_cast<int>(file - (file > 6 ? 1 : 0) - (file > 9 ? 1 : 0));
    worst = std::max(
        worst, (Eigen::Vector2d(r.position[0], r.position[1]) - World::Robot(index).translation().head<2>()).norm());
  }
  EXPECT_LT(worst, 0.005) << "robot position against the truth";
  int crossed = 0;
  for (const auto& e : events.got) {
    ASSERT_EQ(e.num_events, 2);
    crossed += e.events[0].crossed ? 1 : 0;
    EXPECT_GE(e.latency_s, 0);
  }
  EXPECT_GE(crossed, 1);  // the robot passes the VC ray of the block's vertex 0
  VisionSnapshot s{};
  ASSERT_TRUE(latest.TryTake(s));
  EXPECT_EQ(s.frame_seq, robots.got.back().frame_seq);
  EXPECT_TRUE(s.robot_valid);
  EXPECT_EQ(s.num_events, 2);
  std::filesystem::remove_all(dir);
}

// A frame that OpenCV cannot decode in the middle of a video (read() returns false, as at the end) used to
// end the stream silently. A real MJPG AVI is written from rendered frames, one frame's JPEG data is overwritten with
// bytes that hold no JPEG marker, and the video is run through the pipeline: that frame is reported with its number,
// the frames after it are processed (robot against the truth of its frame), and the stream ends at the real end.
TEST(Pipeline, CorruptVideoFrameIsReportedAndTheVideoGoesOn) {
  const World w;
  const auto dir = std::filesystem::temp_directory_path() / ("visco_video_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string video = (dir / "frames.avi").string();
  const int n = 12, corrupt = 5;
  {
    cv::VideoWriter writer(video, cv::VideoWriter::fourcc('M', 'J', 'P', 'G'), 30, cv::Size(kCam.width, kCam.height),
                           false);
    ASSERT_TRUE(writer.isOpened()) << "OpenCV cannot write MJPG/AVI";
    for (int i = 0; i < n; ++i) {
      GrayImage img = w.Render(i);
      writer.write(cv::Mat(img.height, img.width, CV_8UC1, img.pixels.data()));
    }
  }
  // The frames are the AVI's "00dc" chunks whose data starts with a JPEG SOI marker (FF D8); the index repeats the
  // chunk ids without data.
  std::vector<char> bytes;
  {
    std::ifstream in(video, std::ios::binary);
    bytes.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  std::vector<std::size_t> chunks;
  for (std::size_t k = 0; k + 10 < bytes.size(); ++k) {
    if (std::memcmp(&bytes[k], "00dc", 4) == 0 && static_cast<unsigned char>(bytes[k + 8]) == 0xFF &&
        static_cast<unsigned char>(bytes[k + 9]) == 0xD8) {
      chunks.push_back(k);
    }
  }
  ASSERT_EQ(chunks.size(), static_cast<std::size_t>(n));
  std::uint32_t size = 0;
  std::memcpy(&size, &bytes[chunks[corrupt] + 4], 4);
  ASSERT_LT(chunks[corrupt] + 8 + size, bytes.size());
  std::fill_n(bytes.begin() + static_cast<std::ptrdiff_t>(chunks[corrupt] + 8), size, char{0x55});
  {
    std::ofstream out(video, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }

  VisionPipeline pipeline(kCam, w.wMc, w.models, Options());
  std::vector<PipelineOutput> outs;
  PipelineThread thread(MakeVideoSource(video, 1'000'000), pipeline, nullptr, nullptr,
                        [&](const PipelineOutput& o) { outs.push_back(o); });
  thread.Start();
  thread.Join();
  std::filesystem::remove_all(dir);
  EXPECT_EQ(thread.frames(), n - 1);
  EXPECT_EQ(thread.bad_frames(), 1);
  std::vector<std::string> faults;
  std::vector<std::int64_t> processed;
  double worst = 0;
  for (const auto& o : outs) {
    for (const auto& f : o.faults) faults.push_back(f.message);
    if (!o.processed) continue;
    processed.push_back(o.robot.frame_seq);
    ASSERT_TRUE(o.robot.valid) << o.robot.frame_seq;
    const Eigen::Vector2d p(o.robot.position[0], o.robot.position[1]);
    worst = std::max(worst, (p - World::Robot(static_cast<int>(o.robot.frame_seq)).translation().head<2>()).norm());
    if (o.robot.frame_seq == corrupt + 1) {
      EXPECT_TRUE(o.full_detection) << "the prediction skipped a frame";
    }
    // Capture times from the container: 30 fps.
    EXPECT_NEAR(static_cast<double>(o.robot.utime - 1'000'000), o.robot.frame_seq * 1e6 / 30, 2);
  }
  std::vector<std::int64_t> expected;
  for (int i = 0; i < n; ++i) {
    if (i != corrupt) expected.push_back(i);
  }
  EXPECT_EQ(processed, expected);
  ASSERT_EQ(faults.size(), 1u);
  EXPECT_NE(faults[0].find("frame seq 5 "), std::string::npos) << faults[0];
  EXPECT_NE(faults[0].find("cannot read or decode video frame 5"), std::string::npos) << faults[0];
  EXPECT_LT(worst, 0.005) << "robot position against the truth";
  std::printf("corrupt video frame %d: %zu frames processed, fault \"%s\", worst robot position error %.2f mm\n",
              corrupt, processed.size(), faults[0].c_str(), 1e3 * worst);
}

// Frames are ordered by capture time; the counter says what was lost. A gap is reported with the lost
// frames' numbers (and the tracker detects in full again); a counter that goes back while time goes on is a stream
// restart (reported; tracker and features reset), not a reason to reject the camera for ever; a counter that does
// not advance is said once, and its frames are taken.
TEST(Pipeline, GapsRestartsAndCountersThatDoNotAdvanceAreReported) {
  const World w;
  VisionPipeline pipeline(kCam, w.wMc, w.models, Options());
  auto frame = [&](std::int64_t seq, std::int64_t utime) {
    Frame f;
    f.seq = seq;
    f.utime = utime;
    f.image = w.Render(0, true);  // a still scene: only the counter changes
    return f;
  };
  auto messages = [](const PipelineOutput& o) {
    std::string all;
    for (const auto& f : o.faults) all += f.message + "; ";
    return all;
  };
  ASSERT_TRUE(pipeline.Process(frame(10, 1000), 0).processed);
  ASSERT_TRUE(pipeline.Process(frame(11, 2000), 0).processed);
  auto gap = pipeline.Process(frame(15, 3000), 0);
  ASSERT_TRUE(gap.processed);
  EXPECT_TRUE(gap.full_detection) << "the tracker's prediction is void after a gap";
  ASSERT_EQ(gap.faults.size(), 1u) << messages(gap);
  EXPECT_EQ(gap.faults[0].code, visco::fault_t::CODE_VISION_STALE);
  EXPECT_NE(gap.faults[0].message.find("frames 12..14 (3) lost"), std::string::npos) << gap.faults[0].message;
  EXPECT_EQ(pipeline.gaps(), 1);
  auto next = pipeline.Process(frame(16, 4000), 0);
  EXPECT_TRUE(next.faults.empty()) << messages(next);
  EXPECT_FALSE(next.full_detection);

  auto restart = pipeline.Process(frame(0, 5000), 0);
  ASSERT_TRUE(restart.processed) << "a restarted camera is taken, not rejected for ever";
  ASSERT_EQ(restart.faults.size(), 1u) << messages(restart);
  EXPECT_NE(restart.faults[0].message.find("stream restart"), std::string::npos) << restart.faults[0].message;
  EXPECT_TRUE(restart.full_detection);
  EXPECT_EQ(pipeline.restarts(), 1);
  EXPECT_TRUE(restart.robot.valid);

  // A counter stuck at 0: said once, every frame taken.
  auto same = pipeline.Process(frame(0, 6000), 0);
  ASSERT_TRUE(same.processed);
  ASSERT_EQ(same.faults.size(), 1u) << messages(same);
  EXPECT_NE(same.faults[0].message.find("does not advance"), std::string::npos) << same.faults[0].message;
  for (int k = 0; k < 5; ++k) {
    auto again = pipeline.Process(frame(0, 7000 + 1000 * k), 0);
    EXPECT_TRUE(again.processed);
    EXPECT_TRUE(again.faults.empty()) << messages(again);
  }
  EXPECT_EQ(pipeline.gaps(), 1);
  EXPECT_EQ(pipeline.restarts(), 1);
}

TEST(Pipeline, OutOfOrderFramesAndLostRobotAreReported) {
  const World w;
  VisionPipeline pipeline(kCam, w.wMc, w.models, Options());
  auto frame = [&](std::int64_t seq, std::int64_t utime, bool robot) {
    Frame f;
    f.seq = seq;
    f.utime = utime;
    f.image = w.Render(static_cast<int>(seq), robot);
    return f;
  };
  auto a = pipeline.Process(frame(0, 1000, true), 0);
  ASSERT_TRUE(a.processed);
  EXPECT_TRUE(a.robot.valid);
  EXPECT_TRUE(a.faults.empty());
  // Robot and block stand on the table: their published poses are made flush with it (z = 0, upright).
  ASSERT_EQ(a.poses.num_poses, 2);
  for (const auto& p : a.poses.poses) {
    EXPECT_TRUE(p.contact_refined) << p.object_id;
    EXPECT_NEAR(p.position[2], 0, 1e-9) << p.object_id;
    // Quaternion (w, x, y, z) of a rotation about z only.
    EXPECT_NEAR(p.orientation[1], 0, 1e-9) << p.object_id;
    EXPECT_NEAR(p.orientation[2], 0, 1e-9) << p.object_id;
  }
  auto b = pipeline.Process(frame(2, 3000, true), 0);
  ASSERT_TRUE(b.processed);
  auto c = pipeline.Process(frame(1, 2000, true), 0);
  EXPECT_FALSE(c.processed);
  ASSERT_EQ(c.faults.size(), 1u);
  EXPECT_NE(c.faults[0].message.find("out of order"), std::string::npos) << c.faults[0].message;
  EXPECT_EQ(c.faults[0].utime, 2000);
  auto d = pipeline.Process(frame(3, 4000, false), 0);
  ASSERT_TRUE(d.processed);
  EXPECT_FALSE(d.robot.valid);
  EXPECT_FALSE(d.snapshot.robot_valid);
  ASSERT_EQ(d.faults.size(), 1u);
  EXPECT_EQ(d.faults[0].code, visco::fault_t::CODE_VISION_LOST);
  EXPECT_EQ(d.faults[0].utime, 4000);
  EXPECT_EQ(d.events.events[0].state, 0);  // unknown, not the stale last state
  auto e = pipeline.Process(frame(4, 5000, false), 0);
  EXPECT_TRUE(e.faults.empty());  // reported once, not every frame
  auto f = pipeline.Process(frame(5, 6000, true), 0);
  ASSERT_EQ(f.faults.size(), 1u);
  EXPECT_TRUE(f.faults[0].cleared);
  EXPECT_TRUE(f.robot.valid);
  EXPECT_FALSE(f.events.events[0].crossed);  // from unknown: no crossing claimed
}

TEST(Pipeline, DecodesImageMessagesAndRejectsBadOnes) {
  visco::image_t m;
  m.utime = 5;
  m.seq = 9;
  m.width = 4;
  m.height = 2;
  m.row_stride = 5;
  m.pixel_format = visco::image_t::PIXEL_FORMAT_GRAY8;
  m.data.assign(10, 7);
  m.size = 10;
  Frame f;
  std::string err;
  ASSERT_TRUE(DecodeImageMessage(m, f, err)) << err;
  EXPECT_EQ(f.image.width, 4);
  EXPECT_EQ(f.utime, 5);
  m.size = 11;
  EXPECT_FALSE(DecodeImageMessage(m, f, err));
  EXPECT_NE(err.find("size field"), std::string::npos);
  m.size = 10;
  m.row_stride = 6;
  EXPECT_FALSE(DecodeImageMessage(m, f, err));
  EXPECT_NE(err.find("row_stride"), std::string::npos);
  m.pixel_format = visco::image_t::PIXEL_FORMAT_PNG;
  EXPECT_FALSE(DecodeImageMessage(m, f, err));
  EXPECT_NE(err.find("corrupt"), std::string::npos);
  std::vector<std::uint8_t> png;
  cv::imencode(".png", cv::Mat(3, 5, CV_8UC1, cv::Scalar(50)), png);
  m.data = png;
  m.size = static_cast<std::int32_t>(png.size());
  EXPECT_FALSE(DecodeImageMessage(m, f, err));
  EXPECT_NE(err.find("decoded image is 5x3"), std::string::npos) << err;
  m.width = 5;
  m.height = 3;
  EXPECT_TRUE(DecodeImageMessage(m, f, err)) << err;
  m.pixel_format = 42;
  EXPECT_FALSE(DecodeImageMessage(m, f, err));
}

TEST(Pipeline, LcmCameraChannelIn) {
  const World w;
  lcm::LCM bus("memq://");
  ASSERT_TRUE(bus.good());
  auto source = MakeLcmSource(bus, channels::kCameraImage);  // subscribed before the camera publishes
  for (int i = 0; i < 3; ++i) {
    const GrayImage img = w.Render(i);
    visco::image_t m;
    m.utime = 1000 + i;
    m.seq = i;
    m.camera = "synthetic";
    m.width = img.width;
    m.height = img.height;
    m.row_stride = img.width;
    m.pixel_format = visco::image_t::PIXEL_FORMAT_GRAY8;
    m.data = img.pixels;
    m.size = static_cast<std::int32_t>(m.data.size());
    bus.publish(channels::kCameraImage, &m);
  }
  VisionPipeline pipeline(kCam, w.wMc, w.models, Options());
  std::vector<PipelineOutput> outs;
  Frame f;
  std::string err;
  for (int tries = 0; tries < 10 && outs.size() < 3; ++tries) {
    if (source->Next(f, err, 10) == SourceStatus::kFrame) outs.push_back(pipeline.Process(f, NowUtime()));
  }
  ASSERT_EQ(outs.size(), 3u);
  for (const auto& o : outs) EXPECT_TRUE(o.robot.valid);
  EXPECT_EQ(outs[2].detections.camera, "synthetic");
}

// Streams: 640x480 GRAY8 frames (307 kB each) published at 30 Hz over a real LCM bus (UDP multicast,
// ttl=0, a private port; the receiver with LCM's recv_buf_size, as docs/vision.md says a tracker over udpm must) into
// the LCM frame source and the pipeline thread. Every published frame must be processed (0 lost); then three frames
// are dropped on purpose (not published) and the gap must be reported with their numbers.
TEST(Pipeline, LcmStreamAt30HzLosesNoFrameAndReportsDroppedOnes) {
#if defined(__SANITIZE_THREAD__)
  const double hz = 10;  // ThreadSanitizer slows detection ~10x: the loss check at a rate the build can follow
#else
  const double hz = 30;
#endif
  const World w;
  const int n = test_world::SanitizedCount(120, 60);
  const int drop_from = n - 20, dropped = 3;  // seq drop_from .. drop_from + 2 are never published
  std::vector<GrayImage> frames;
  for (int i = 0; i < n; ++i) frames.push_back(w.RenderAt(Planar(-0.16 + 0.3 * i / n, 0.0, 0.1), 500 + i));
  const std::string url = "udpm://239.255.76.67:" + std::to_string(45000 + ::getpid() % 15000) + "?ttl=0";
  lcm::LCM rx(url + "&recv_buf_size=2097152");
  lcm::LCM tx(url);
  ASSERT_TRUE(rx.good() && tx.good()) << url;
  VisionPipeline pipeline(kCam, w.wMc, w.models, Options());
  std::mutex mu;
  std::vector<std::int64_t> processed;
  std::vector<std::string> faults;
  PipelineThread thread(MakeLcmSource(rx, channels::kCameraImage), pipeline, nullptr, nullptr,
                        [&](const PipelineOutput& o) {
                          std::lock_guard<std::mutex> lock(mu);
                          if (o.processed) processed.push_back(o.robot.frame_seq);
                          for (const auto& f : o.faults) faults.push_back(f.message);
                        });
  thread.Start();
  std::this_thread::sleep_for(std::chrono::milliseconds(200));  // the thread subscribed and waits
  const auto period = std::chrono::microseconds(static_cast<std::int64_t>(1e6 / hz));
  auto next = std::chrono::steady_clock::now();
  std::vector<std::int64_t> published;
  for (int i = 0; i < n; ++i) {
    std::this_thread::sleep_until(next);
    next += period;
    if (i >= drop_from && i < drop_from + dropped) continue;
    visco::image_t m;
    m.utime = 1'000'000 + static_cast<std::int64_t>(i * 1e6 / hz);
    m.seq = i;
    m.camera = "synthetic";
    m.width = frames[static_cast<std::size_t>(i)].width;
    m.height = frames[static_cast<std::size_t>(i)].height;
    m.row_stride = m.width;
    m.pixel_format = visco::image_t::PIXEL_FORMAT_GRAY8;
    m.data = frames[static_cast<std::size_t>(i)].pixels;
    m.size = static_cast<std::int32_t>(m.data.size());
    ASSERT_EQ(tx.publish(channels::kCameraImage, &m), 0);
    published.push_back(i);
  }
  // Wait for the last frame (at most 2 s), then stop.
  for (int k = 0; k < 200; ++k) {
    {
      std::lock_guard<std::mutex> lock(mu);
      if (!processed.empty() && processed.back() == n - 1) break;
    }
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  }
  thread.Stop();
  std::lock_guard<std::mutex> lock(mu);
  std::string all;
  for (const auto& f : faults) all += f + "; ";
  std::printf("LCM udpm at %.0f Hz, 640x480: %zu frames published, %zu processed, faults: %s\n", hz, published.size(),
              processed.size(), all.c_str());
  EXPECT_EQ(processed, published) << "frames lost between the bus and the pipeline";
  ASSERT_EQ(faults.size(), 1u) << all;
  const std::string expected = "frames " + std::to_string(drop_from) + ".." + std::to_string(drop_from + dropped - 1) +
                               " (" + std::to_string(dropped) + ") lost before frame seq " +
                               std::to_string(drop_from + dropped) + " ";
  EXPECT_NE(faults[0].find(expected), std::string::npos) << faults[0];
  EXPECT_EQ(pipeline.gaps(), 1);
}

}  // namespace
}  // namespace visco::vision
