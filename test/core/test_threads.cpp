// The threaded paths of the core, written to be run under ThreadSanitizer (test/sanitize, KP_SANITIZER=thread:
// clang with LLVM's libomp, so that OpenMP's own synchronisation is visible) as well as in the normal build:
// the OpenMP per-row loop of Pipeline::process, several pipelines on several threads, and the node's way of
// changing settings between frames (SettingsExchange + FramePipeline) with changes posted at 100 Hz and faster
// while frames are processed. Each frame must equal, bit for bit, the frame of a fresh pipeline made with the one
// config it was processed with: a torn config (half of one change) would give neither.
#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/settings_exchange.h"
#include "kinect_pipeline/tools/synthetic.h"
#include "test_util.h"

using namespace kinect_pipeline;

namespace
{
// Small frames: ThreadSanitizer makes each memory access several times slower.
Camera smallCamera() { return Camera::fromFov(128, 106, 70.6 * M_PI / 180, 60 * M_PI / 180); }

Scene scene()
{
  Scene s;
  s.ceiling = 2.7;
  s.boxes = {{1.5, 2.0, -0.4, 0.3, 0.0, 0.6}, {2.5, 2.9, 0.5, 1.0, 0.0, 1.8}, {3.0, 3.3, -1.2, -0.9, 0.0, 0.05}};
  s.holes = {{2.0, 2.4, -1.2, -0.6, 0, 0}};
  return s;
}

cv::Mat frame(const Camera& cam, double pitch, int type, std::uint64_t seed)
{
  Rendering gt;
  renderScene(cam, 1.1, pitch, 0.02, scene(), gt);
  cv::Mat m = gt.depth.clone();
  addKinectNoise(m, seed);
  return encodeDepth(m, type, 12.0);
}


bool sameRanges(const std::vector<float>& a, const std::vector<float>& b)
{
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

/** What a frame gives that does not depend on the history (the confidence does). */
struct Expected
{
  cv::Mat depth, labels;
  std::vector<float> ranges;
};

Expected expect(const Camera& cam, const Config& cfg, const cv::Mat& depth, const SensorPose& pose)
{
  Pipeline p(cam, cfg);
  FrameResult r;
  p.process(depth, pose, r);
  return {r.depth.clone(), r.labels.clone(), r.scan.ranges};
}

bool matches(const FrameResult& r, const Expected& e)
{
  return kp_test::sameBits(r.depth, e.depth) && kp_test::sameBits(r.labels, e.labels) && sameRanges(r.scan.ranges, e.ranges);
}

/** Settings as the node has them: the core's config plus its own fields, swapped in whole. */
struct Settings
{
  Config core;
  int id = 0;
};

/**
 * The default config without the floor refinement's learning: the learned correction makes a frame depend on the
 * frames before it; without it each frame depends on itself alone, which is what these tests compare (the fit
 * itself still runs on every frame).
 */
Config historyFree()
{
  Config c;
  c.floor_learn_time = 0.0;
  return c;
}

/** Configs that differ in fields read at different places of a frame (beams, limits, kernel, geometry). */
std::vector<Config> configs()
{
  std::vector<Config> v(4, historyFree());
  v[0].num_threads = 2;
  v[1].num_threads = 3;
  v[1].scan_beams = 64;
  v[1].range_max = 2.5;
  v[1].open_kernel_size = 5;
  v[2].num_threads = 2;
  v[2].projection = Projection::kColumn;
  v[2].open_kernel_shape = KernelShape::kCross;
  v[2].ceiling_height = 1.6;
  v[3].num_threads = 4;
  v[3].geometry = Geometry::kThesis;
  v[3].open_kernel_size = 0;
  v[3].range_min = 1.0;
  v[3].threshold_curve = {{0.5, 0.05}, {4.0, 0.2}};
  v[3].surface_band = 0.5;
  return v;
}
}  // namespace

TEST(Threads, OpenMpTeamsGiveTheFrameOfOneThread)
{
  const Camera cam = smallCamera();
  const SensorPose pose{1.1, 0.3, 0.02};
  for (int type : {CV_8UC1, CV_16UC1, CV_32FC1})
    for (KernelShape shape : {KernelShape::kRect, KernelShape::kEllipse})
    {
      const cv::Mat depth = frame(cam, 0.3, type, 3);
      Config one = historyFree();
      one.num_threads = 1;
      one.open_kernel_shape = shape;
      one.surface_band = shape == KernelShape::kRect ? 0.0 : 1.0;  // its second pass sums integers: any team
      const Expected e = expect(cam, one, depth, pose);
      for (int threads : {2, 4})
      {
        Config many = one;
        many.num_threads = threads;
        Pipeline p(cam, many);
        FrameResult r;
        for (int i = 0; i < 3; ++i)  // the buffers are reused from the second frame on
        {
          p.process(depth, pose, r);
          EXPECT_TRUE(matches(r, e)) << "type " << type << ", " << threads << " threads, frame " << i;
        }
      }
    }
}

TEST(Threads, SeveralPipelinesOnSeveralThreads)
{
  const Camera cam = smallCamera();
  constexpr int kThreads = 4, kFrames = 12;
  std::vector<cv::Mat> frames;
  std::vector<SensorPose> poses;
  for (int i = 0; i < kFrames; ++i)
  {
    poses.push_back({1.1, 0.3 + 0.01 * (i % 5), 0.02});
    frames.push_back(frame(cam, poses.back().pitch, i % 2 ? CV_16UC1 : CV_32FC1, 10 + i));
  }
  Config cfg = historyFree();
  cfg.num_threads = 2;
  std::vector<Expected> expected;
  for (int i = 0; i < kFrames; ++i)
    expected.push_back(expect(cam, cfg, frames[i], poses[i]));

  std::vector<int> mismatches(kThreads, 0);
  std::vector<std::thread> workers;
  for (int t = 0; t < kThreads; ++t)
    workers.emplace_back([&, t] {
      Pipeline p(cam, cfg);
      FrameResult r;
      for (int k = 0; k < 2 * kFrames; ++k)
      {
        const int i = (k + t) % kFrames;  // each thread in its own order
        p.process(frames[i], poses[i], r);
        if (!matches(r, expected[i]))
          ++mismatches[t];
      }
    });
  for (auto& w : workers)
    w.join();
  for (int t = 0; t < kThreads; ++t)
    EXPECT_EQ(mismatches[t], 0) << "thread " << t;
}

TEST(Threads, SettingsExchangeKeepsTheNewestAndHandsItOverOnce)
{
  SettingsExchange<Settings> ex;
  std::shared_ptr<const Settings> active;
  EXPECT_FALSE(ex.take(active));
  EXPECT_EQ(active, nullptr);
  auto a = std::make_shared<const Settings>(Settings{Config(), 1});
  auto b = std::make_shared<const Settings>(Settings{Config(), 2});
  ex.post(a);
  ex.post(b);
  ex.post(nullptr);  // ignored
  EXPECT_TRUE(ex.take(active));
  EXPECT_EQ(active, b);
  EXPECT_FALSE(ex.take(active));
  EXPECT_EQ(active, b);
  EXPECT_EQ(ex.posted(), 2u);
}

TEST(Threads, FramePipelineFollowsConfigAndCamera)
{
  const Camera cam = smallCamera();
  const Camera half = Camera::fromFov(64, 53, 70.6 * M_PI / 180, 60 * M_PI / 180);
  const SensorPose pose{1.1, 0.3, 0.02};
  const std::vector<Config> cfgs = configs();
  FramePipeline fp;
  FrameResult r;
  auto c0 = std::make_shared<const Config>(cfgs[0]);
  auto c1 = std::make_shared<const Config>(cfgs[1]);
  const cv::Mat big = frame(cam, 0.3, CV_16UC1, 1), small = frame(half, 0.3, CV_16UC1, 1);
  fp.process(c0, cam, big, pose, r);
  EXPECT_TRUE(matches(r, expect(cam, cfgs[0], big, pose)));
  fp.process(c1, cam, big, pose, r);
  EXPECT_TRUE(matches(r, expect(cam, cfgs[1], big, pose)));
  fp.process(c1, half, small, pose, r);  // the camera changed its resolution
  EXPECT_TRUE(matches(r, expect(half, cfgs[1], small, pose)));
  EXPECT_EQ(fp.configChanges(), 2u);
  // A refused config leaves the one in force.
  Config bad = cfgs[0];
  bad.range_max = 0.0;
  EXPECT_THROW(fp.process(std::make_shared<const Config>(bad), half, small, pose, r), std::invalid_argument);
  EXPECT_EQ(fp.config(), c1);
  fp.process(c1, half, small, pose, r);
  EXPECT_TRUE(matches(r, expect(half, cfgs[1], small, pose)));
  EXPECT_THROW(fp.process(nullptr, half, small, pose, r), std::invalid_argument);
}

// The node's way: the parameter thread posts whole settings, the frame thread takes the newest between frames.
void settingsChangeWhileFramesFlow(std::chrono::microseconds period, int min_posts)
{
  const Camera cam = smallCamera();
  const SensorPose pose{1.1, 0.3, 0.02};
  const std::vector<Config> cfgs = configs();
  const cv::Mat depth = frame(cam, 0.3, CV_16UC1, 7);
  std::vector<Expected> expected;
  for (const Config& c : cfgs)
    expected.push_back(expect(cam, c, depth, pose));

  SettingsExchange<Settings> exchange;
  exchange.post(std::make_shared<const Settings>(Settings{cfgs[0], 0}));
  std::atomic<bool> stop{false};
  std::thread poster([&] {
    auto next = std::chrono::steady_clock::now();
    for (int i = 1; !stop.load(); ++i)
    {
      const int id = i % static_cast<int>(cfgs.size());
      exchange.post(std::make_shared<const Settings>(Settings{cfgs[id], id}));
      next += period;
      std::this_thread::sleep_until(next);
    }
  });

  FramePipeline fp;
  FrameResult r;
  std::shared_ptr<const Settings> active;
  int frames = 0, bad = 0, changes = 0;
  std::vector<int> seen(cfgs.size(), 0);
  // Runs until the poster has posted enough changes and the frames have taken two of them (not a time limit: a slow
  // or busy machine, whose scheduler may leave one thread waiting for a while, just takes longer; the deadline
  // is for a change that never arrives).
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
  while ((exchange.posted() < static_cast<std::uint64_t>(min_posts) || frames < 20 || changes < 2) &&
         std::chrono::steady_clock::now() < deadline)
  {
    if (exchange.take(active))
      ++changes;
    fp.process(std::shared_ptr<const Config>(active, &active->core), cam, depth, pose, r);
    ++frames;
    ++seen[active->id];
    if (!matches(r, expected[active->id]) || r.scan.ranges.size() != expected[active->id].ranges.size())
      ++bad;
  }
  stop = true;
  poster.join();
  EXPECT_EQ(bad, 0) << "of " << frames << " frames";
  EXPECT_GE(changes, 2) << "the settings never changed while frames were processed";
  EXPECT_EQ(fp.configChanges(), static_cast<std::uint64_t>(changes));
  std::printf("[ info ] %d frames, %llu settings posted, %d taken; frames per config:", frames,
              static_cast<unsigned long long>(exchange.posted()), changes);
  for (int n : seen)
    std::printf(" %d", n);
  std::printf("\n");
}

TEST(Threads, SettingsChangeAt100HzWhileFramesFlow) { settingsChangeWhileFramesFlow(std::chrono::milliseconds(10), 60); }

TEST(Threads, SettingsChangeAsFastAsPossibleWhileFramesFlow)
{
  settingsChangeWhileFramesFlow(std::chrono::microseconds(0), 2000);
}

#ifdef KP_TSAN_CANARY
// A planted race, only in the TSan build and disabled there: scripts/run_tests.sh runs it alone and requires a
// report, so a TSan set-up that hides OpenMP's races (a wrong runtime, a too broad option) fails the test command.
TEST(Threads, DISABLED_RaceCanary)
{
  int shared = 0;
#pragma omp parallel for num_threads(2) schedule(static)
  for (int i = 0; i < 1000; ++i)
    shared += i;  // unsynchronised read-modify-write from two threads
  Config cfg;
  std::thread writer([&] { cfg.range_max = 5.0; });
  const double seen = cfg.range_max;  // unsynchronised with the writer
  writer.join();
  EXPECT_GE(shared + seen, 0.0);
}
#endif
