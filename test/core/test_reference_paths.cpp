// The core's fast paths against its reference paths (ReferencePaths, per Pipeline: the rule pixel by pixel, the
// binning by pixel centres, cv::morphologyEx for the opening), on every scene, encoding and projection, with and
// without roll and upside down, for each opening kernel: the labelling by value and the row kernels of the opening
// claim the reference's bits; the binning from the bins' borders claims the centres' bins up to float rounding at a
// border. (Every SIMD target against the plain loops: the *EveryTarget* tests.)
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <map>
#include <string>
#include <tuple>

#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/tools/synthetic.h"
#include "test_scenes.h"
#include "test_util.h"

using namespace kinect_pipeline;

namespace
{
Camera kinect() { return Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180); }

struct Case
{
  int type;
  const char* scene;
  double pitch, roll;
  int kernel;
  Projection projection;
  double scan_fov = 0.0;
};

std::string name(const Case& c)
{
  const char* roll = c.roll == 0.0 ? "" : (std::fabs(c.roll) == M_PI ? "_upside_down" : "_roll");
  return cv::typeToString(c.type) + "_" + c.scene + "_pitch" + std::to_string(std::lround(c.pitch * 1000)) + roll +
         (std::fabs(c.roll) > M_PI / 2 && std::fabs(c.roll) < M_PI ? "_over" : "") + "_k" + std::to_string(c.kernel) + "_" + toString(c.projection) +
         (c.scan_fov > 0.0 ? "_all_round" : "");
}

void PrintTo(const Case& c, std::ostream* os) { *os << name(c); }

// Noisy metres of a scene seen from 1.1 m (rendered once per scene and pose).
const cv::Mat& metres(const Camera& cam, const std::string& scene, double pitch, double roll)
{
  static std::map<std::tuple<std::string, double, double>, cv::Mat> cache;
  cv::Mat& m = cache[{scene, pitch, roll}];
  if (m.empty())
  {
    Scene s = scene == "lab"     ? kp_test::labScene()
              : scene == "boxes" ? kp_test::boxesScene()
              : scene == "hole"  ? kp_test::holeScene()
                                 : kp_test::stairScene();
    if (scene == "around")  // boxes beside and behind the sensor's foot, seen looking steeply down
      s.boxes = {{-0.9, -0.5, -0.5, 0.4, 0.0, 0.5}, {0.2, 0.5, -0.9, -0.6, 0.0, 0.3}, {-0.3, 0.1, 0.5, 0.8, 0.0, 0.8}};
    Rendering gt;
    renderScene(cam, 1.1, pitch, roll, s, gt);
    m = gt.depth.clone();
    addKinectNoise(m, 11);
  }
  return m;
}

bool sameBits(const std::vector<float>& a, const std::vector<float>& b)
{
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size() * sizeof(float)) == 0;
}

using kp_test::sameBits;

// One frame through a fresh pipeline with the given paths.
FrameResult processWith(const Camera& cam, const Config& cfg, const cv::Mat& frame, const Case& c,
                        const ReferencePaths& paths)
{
  Pipeline pipe(cam, cfg, paths);
  FrameResult res;
  pipe.process(frame, SensorPose{1.1, c.pitch, c.roll}, res);
  return res;
}

// The beams where the two scans differ by more than a few float roundings (relative 1e-6: the squared and the plain
// ranges' roundings). Each must be a pixel that one binning put in the beam and the other in a neighbouring one (its
// centre within rounding of the border between them): where a[k] < b[k], b has a range no farther than a[k] a beam
// either side (and the other way round); else the difference is counted in unexplained.
int borderBeams(const std::vector<float>& a, const std::vector<float>& b, int& unexplained)
{
  const auto close = [](float x, float y) {
    return x == y || (std::isnan(x) && std::isnan(y)) || std::fabs(x - y) <= 1e-6f * std::fabs(x);
  };
  const int n = static_cast<int>(a.size());
  int differ = 0;
  for (int k = 0; k < n; ++k)
  {
    if (close(a[k], b[k]))
      continue;
    ++differ;
    const std::vector<float>& far = a[k] < b[k] ? b : a;  // the scan that put the nearer pixel elsewhere
    const float nearer = std::min(a[k], b[k]) * (1.0f + 1e-6f);
    const bool moved = (k > 0 && far[k - 1] <= nearer) || (k + 1 < n && far[k + 1] <= nearer);
    unexplained += !moved;
    if (!moved)
      ADD_FAILURE() << "beam " << k << ": " << a[k] << " vs " << b[k] << ", neighbours " << (k > 0 ? a[k - 1] : NAN)
                    << " " << (k + 1 < n ? a[k + 1] : NAN) << " vs " << (k > 0 ? b[k - 1] : NAN) << " "
                    << (k + 1 < n ? b[k + 1] : NAN);
  }
  return differ;
}
}  // namespace

class FastVsReference : public ::testing::TestWithParam<Case>
{
};

TEST_P(FastVsReference, SameBitsButForTheBinningsBorders)
{
  const Case c = GetParam();
  const Camera cam = kinect();
  Config cfg;
  cfg.open_kernel_size = c.kernel;
  cfg.projection = c.projection;
  cfg.refine_floor = false;
  cfg.cliff_scan = true;
  cfg.scan_fov = c.scan_fov;
  const cv::Mat frame = encodeDepth(metres(cam, c.scene, c.pitch, c.roll), c.type, cfg.max_depth);
  const FrameResult fast = processWith(cam, cfg, frame, c, {});
  // The labelling by value and the opening's row kernels against the rule pixel by pixel and OpenCV's opening:
  // every output, bit for bit (the binning is the same).
  const FrameResult plain = processWith(cam, cfg, frame, c, {true, false, true});
  EXPECT_TRUE(sameBits(fast.labels, plain.labels));
  EXPECT_TRUE(sameBits(fast.depth, plain.depth));
  EXPECT_EQ(fast.counts, plain.counts);
  EXPECT_TRUE(sameBits(fast.scan.ranges, plain.scan.ranges));
  EXPECT_TRUE(sameBits(fast.scan.intensities, plain.scan.intensities));
  EXPECT_TRUE(sameBits(fast.cliff.ranges, plain.cliff.ranges));
  // The whole reference path: the same labels and depth; the beams as the centres' binning gives them.
  const FrameResult ref = processWith(cam, cfg, frame, c, ReferencePaths::all());
  EXPECT_TRUE(sameBits(fast.labels, ref.labels));
  EXPECT_TRUE(sameBits(fast.depth, ref.depth));
  EXPECT_EQ(fast.counts, ref.counts);
  int unexplained = 0;
  const int scan = borderBeams(fast.scan.ranges, ref.scan.ranges, unexplained);
  const int cliff = borderBeams(fast.cliff.ranges, ref.cliff.ranges, unexplained);
  EXPECT_EQ(unexplained, 0) << "beams whose ranges differ other than by a pixel at a bin border";
  // At most a few beams a scan (at most 1 in these cases when this was written).
  EXPECT_LE(scan, 4) << "of " << fast.scan.ranges.size() << " beams";
  EXPECT_LE(cliff, 4) << "of " << fast.cliff.ranges.size() << " beams";
  if (c.projection == Projection::kColumn)  // both bin the columns' centres
  {
    EXPECT_TRUE(sameBits(fast.scan.ranges, ref.scan.ranges));
    EXPECT_TRUE(sameBits(fast.cliff.ranges, ref.cliff.ranges));
  }
  RecordProperty("border_beams", scan + cliff);
}

std::vector<Case> cases()
{
  std::vector<Case> out;
  for (const int type : {CV_8UC1, CV_16UC1, CV_32FC1})
    for (const char* scene : {"lab", "boxes", "hole", "stair"})
      for (const auto& [pitch, roll] : {std::pair{0.26, 0.0}, {0.35, 0.035}})
        for (const int kernel : {0, 3, 5})
          for (const Projection p : {Projection::kHorizontal, Projection::kColumn})
            out.push_back({type, scene, pitch, roll, kernel, p});
  // Looking steeply down with a scan all round: the lowest rows look behind the sensor, where bearings grow with
  // the column (the crossings' other direction).
  for (const int type : {CV_8UC1, CV_16UC1, CV_32FC1})
    for (const auto& [pitch, roll] : {std::pair{1.3, 0.0}, {1.45, 0.03}})
      out.push_back({type, "around", pitch, roll, 3, Projection::kHorizontal, 2.0 * M_PI});
  // Upside down (roll pi: the paths of a level mount, rows of one rise each) and rolled past it.
  for (const int type : {CV_8UC1, CV_16UC1, CV_32FC1})
    for (const char* scene : {"lab", "hole"})
      for (const auto& [pitch, roll] : {std::pair{0.26, M_PI}, {0.35, -M_PI + 0.035}})
        for (const Projection p : {Projection::kHorizontal, Projection::kColumn})
          out.push_back({type, scene, pitch, roll, 3, p});
  return out;
}

INSTANTIATE_TEST_SUITE_P(Scenes, FastVsReference, ::testing::ValuesIn(cases()),
                         [](const ::testing::TestParamInfo<Case>& i) { return name(i.param); });

// The reference binning is not the fast one: at least one beam of the horizontal projection gets its range with
// other roundings (the squared range of the kept pixels against the range squared), so the switch reaches it.
TEST(ReferencePaths, TheReferenceBinningRuns)
{
  const Camera cam = kinect();
  Config cfg;
  cfg.refine_floor = false;
  const Case c{CV_16UC1, "lab", 0.26, 0.0, 3, Projection::kHorizontal};
  const cv::Mat frame = encodeDepth(metres(cam, c.scene, c.pitch, c.roll), c.type, cfg.max_depth);
  const FrameResult fast = processWith(cam, cfg, frame, c, {});
  const FrameResult ref = processWith(cam, cfg, frame, c, ReferencePaths::all());
  int other_bits = 0;
  for (std::size_t k = 0; k < fast.scan.ranges.size(); ++k)
    other_bits += std::isfinite(fast.scan.ranges[k]) && fast.scan.ranges[k] != ref.scan.ranges[k];
  EXPECT_GT(other_bits, 0);
}

// The choice is the pipeline's own: a fast and a reference pipeline held at once, their frames interleaved, give
// what each gives alone.
TEST(ReferencePaths, EachPipelineTakesItsOwnPaths)
{
  const Camera cam = kinect();
  Config cfg;
  cfg.refine_floor = false;
  const Case c{CV_16UC1, "lab", 0.26, 0.0, 3, Projection::kHorizontal};
  const cv::Mat frame = encodeDepth(metres(cam, c.scene, c.pitch, c.roll), c.type, cfg.max_depth);
  Pipeline fast(cam, cfg), ref(cam, cfg, ReferencePaths::all());
  EXPECT_FALSE(fast.referencePaths().binning);
  EXPECT_TRUE(ref.referencePaths().binning);
  FrameResult a, b;
  fast.process(frame, SensorPose{1.1, c.pitch, c.roll}, a);
  ref.process(frame, SensorPose{1.1, c.pitch, c.roll}, b);
  const FrameResult alone_fast = processWith(cam, cfg, frame, c, {});
  const FrameResult alone_ref = processWith(cam, cfg, frame, c, ReferencePaths::all());
  EXPECT_TRUE(sameBits(a.scan.ranges, alone_fast.scan.ranges));
  EXPECT_TRUE(sameBits(b.scan.ranges, alone_ref.scan.ranges));
  EXPECT_FALSE(sameBits(a.scan.ranges, b.scan.ranges)) << "the reference binning's roundings (TheReferenceBinningRuns)";
  EXPECT_TRUE(sameBits(a.labels, b.labels));
}

// With a floor profile (stages/floor_profile.h) the rule's floor offset varies with the ray: the labelling by value
// takes each row's, the rule pixel by pixel each pixel's, the cliff binning each below-floor pixel's. A profile of
// 5 cm of depth per metre (restored, not learned: floor_learn_time 0 keeps it) must give the same bits on the fast
// and the plain paths, with and without roll (small ones: rows of a few lift steps, looked up in a vector or by runs;
// 0.06 rad: rows of more steps than the runs take), for every encoding, and other labels than no profile; on every
// SIMD target.
TEST(ReferencePaths, TheFloorProfileKeepsTheLabellingsBits)
{
  const Camera cam = kinect();
  FloorFit::State state;
  for (int k = 0; k < FloorProfileBands::kBands; ++k)
    state.profile.bias[k] = (k % 2 ? -0.05f : 0.05f) * (k + 0.5f) * FloorProfileBands::kBandWidth;
  kp_test::forEachSimdTarget([&](const std::string& target) {
    for (const int type : {CV_8UC1, CV_16UC1, CV_32FC1})
      for (const char* scene : {"lab", "stair"})
        for (const auto& [pitch, roll] : {std::pair{0.35, 0.0}, {0.35, 0.002}, {0.35, -0.02}, {0.35, 0.06}})
        {
          SCOPED_TRACE(target + " " + cv::typeToString(type) + " " + scene + " roll " + std::to_string(roll));
          Config cfg;
          cfg.cliff_scan = true;
          cfg.floor_learn_time = 0.0;
          cfg.floor_profile_max = 0.1;
          Pipeline fast(cam, cfg), plain(cam, cfg, {true, false, true});
          fast.restoreFloorFit(state);
          plain.restoreFloorFit(state);
          cfg.floor_profile_max = 0.0;
          Pipeline none(cam, cfg);
          const cv::Mat frame = encodeDepth(metres(cam, scene, pitch, roll), type, cfg.max_depth);
          FrameResult a, b, c;
          fast.process(frame, SensorPose{1.1, pitch, roll}, a);
          plain.process(frame, SensorPose{1.1, pitch, roll}, b);
          none.process(frame, SensorPose{1.1, pitch, roll}, c);
          EXPECT_TRUE(sameBits(a.labels, b.labels));
          EXPECT_TRUE(sameBits(a.depth, b.depth));
          EXPECT_TRUE(sameBits(a.scan.ranges, b.scan.ranges));
          EXPECT_TRUE(sameBits(a.cliff.ranges, b.cliff.ranges));
          EXPECT_EQ(a.floor_fit.profile.bias, state.profile.bias);
          EXPECT_FALSE(sameBits(a.labels, c.labels)) << "the profile changed no label: the test would not reach it";
        }
  });
}
