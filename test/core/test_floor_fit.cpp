// The floor refinement (stages/floor_fit.h) against obvious references written here: the renderer's true pose, a plain
// least-squares plane through the fit's own sampled pixels, and the pose/plane geometry by explicit matrices.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <opencv2/core.hpp>

#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/stages/floor_fit.h"
#include "kinect_pipeline/tools/synthetic.h"
#include "test_util.h"

using namespace kinect_pipeline;

namespace
{
constexpr double kDeg = 3.14159265358979323846 / 180.0;

Camera kinect() { return Camera(512, 424, 365.5, 365.5, 255.5, 211.5); }

/** A frame of @p scene rendered at the true pose, encoded as @p type; noise if seed > 0. */
cv::Mat frameOf(const Scene& scene, const SensorPose& truth, int type, std::uint64_t seed = 0)
{
  Rendering r;
  renderScene(kinect(), truth.height, truth.pitch, truth.roll, scene, r);
  cv::Mat m = r.depth.clone();
  if (seed)
    addKinectNoise(m, seed);
  return encodeDepth(m, type, 12.0);
}

struct Told
{
  double dh, dp, dr;  // told pose minus true [m, deg, deg]
};

const Told kErrors[] = {{0, 0, 0},        {0.05, 0, 0},  {-0.05, 0, 0},   {0, 1, 0},       {0, -1, 0},
                        {0, 0, 1},        {0, 0, -1},    {0.05, 1, 1},    {-0.05, -1, 1},  {0.05, -1, -1},
                        {-0.05, 1, -1},   {0.02, -0.5, 0.5}};

SensorPose told(const SensorPose& t, const Told& e)
{
  return {t.height + e.dh, t.pitch + e.dp * kDeg, t.roll + e.dr * kDeg};
}

/** The pose a pipeline with the default refinement processes @p depth at, told @p prior. */
FrameResult refined(const cv::Mat& depth, const SensorPose& prior, Config cfg = Config())
{
  Pipeline p(kinect(), cfg);
  FrameResult out;
  p.process(depth, prior, out);
  return out;
}

/** Level-frame coordinates of an optical-frame point under a pose, by explicit matrices (kp_test::rayWorld). */
kp_test::V3 levelOf(const Camera& c, double u, double v, double depth, const SensorPose& p)
{
  const kp_test::V3 d = kp_test::rayWorld(c, u, v, p.pitch, p.roll);
  return {d.x * depth, d.y * depth, d.z * depth};
}
}  // namespace

TEST(FloorFit, PoseFromFloorPlaneHasThatPlaneAsItsFloor)
{
  // Points on the plane z = a + b x + c y of the prior's level frame must lie at height 0 under the pose returned.
  const Camera cam = kinect();
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> small(-0.03, 0.03), tilt(-0.5, 0.5);
  for (int trial = 0; trial < 50; ++trial)
  {
    const SensorPose prior{1.0 + small(rng) * 10, tilt(rng), 0.3 * tilt(rng)};
    const double a = -prior.height + small(rng), b = small(rng), c = small(rng);
    const SensorPose pose = poseFromFloorPlane(prior, a, b, c);
    for (const auto& px : {std::array<double, 2>{100, 400}, {256, 300}, {450, 350}, {30, 250}})
    {
      // Where the pixel's ray under the prior meets the plane: t * d.z = a + b t d.x + c t d.y.
      const kp_test::V3 d = kp_test::rayWorld(cam, px[0], px[1], prior.pitch, prior.roll);
      const double t = a / (d.z - b * d.x - c * d.y);
      if (!(t > 0.0))
        continue;
      // The same optical point under the new pose: its height above the floor is h + z_level.
      const kp_test::V3 q = levelOf(cam, px[0], px[1], t, pose);
      EXPECT_NEAR(pose.height + q.z, 0.0, 1e-9) << "trial " << trial;
    }
  }
}

TEST(FloorFit, PoseFromFloorPlaneOfThePriorsOwnFloorIsThePrior)
{
  for (const SensorPose p : {SensorPose{1.1, 0.26, 0.0}, SensorPose{0.4, -0.3, 0.2}, SensorPose{2.0, 1.2, -0.6}})
  {
    const SensorPose q = poseFromFloorPlane(p, -p.height, 0.0, 0.0);
    EXPECT_NEAR(q.height, p.height, 1e-12);
    EXPECT_NEAR(q.pitch, p.pitch, 1e-12);
    EXPECT_NEAR(q.roll, p.roll, 1e-12);
  }
}

TEST(FloorFit, RecoversTheTruePoseOfAnEmptyFloor)
{
  // Noise-free floors told a wrong pose: the fit lands on the renderer's pose, in every encoding.
  for (const int type : {CV_8UC1, CV_16UC1, CV_32FC1})
    for (const SensorPose truth : {SensorPose{1.1, 10 * kDeg, 0.0}, SensorPose{1.1, 20 * kDeg, 0.0},
                                   SensorPose{0.6, 25 * kDeg, 3 * kDeg}, SensorPose{1.4, 14 * kDeg, -2 * kDeg}})
    {
      const cv::Mat depth = frameOf(Scene{}, truth, type);
      // 8-bit steps are 4.7 cm: its rows' rounding leaves millimetres and a tenth of a degree (1 cm at 6 m, where
      // its threshold is 4.7 cm or more)
      const double tol_h = type == CV_8UC1 ? 0.004 : 0.0005, tol_a = (type == CV_8UC1 ? 0.1 : 0.01) * kDeg;
      for (const Told& e : kErrors)
      {
        const FrameResult r = refined(depth, told(truth, e));
        SCOPED_TRACE(::testing::Message() << "type " << type << " truth " << truth.height << "/" << truth.pitch
                                          << "/" << truth.roll << " error " << e.dh << "/" << e.dp << "/" << e.dr);
        ASSERT_EQ(r.floor_fit.status, FloorFitStatus::kAccepted) << toString(r.floor_fit.status);
        EXPECT_NEAR(r.pose.height, truth.height, tol_h);
        EXPECT_NEAR(r.pose.pitch, truth.pitch, tol_a);
        EXPECT_NEAR(r.pose.roll, truth.roll, tol_a);
        EXPECT_NEAR(r.floor_fit.applied.height, truth.height - told(truth, e).height, 1e-12 + tol_h);
      }
    }
}

TEST(FloorFit, RecoversAnUpsideDownPoseAcrossPlusMinusPi)
{
  // An upside-down camera, rolled to either side of +-180 deg, told a roll on the other side (or pi + 1 deg, which
  // the pipeline takes as -pi + 1 deg): the fit lands on the renderer's pose, the roll turned into [-pi, pi].
  for (const int type : {CV_16UC1, CV_32FC1})
    for (const double roll : {M_PI, M_PI - 0.5 * kDeg, -M_PI + 0.5 * kDeg})
    {
      const SensorPose truth{1.0, 15 * kDeg, roll};
      const cv::Mat depth = frameOf(Scene{}, truth, type);
      for (const double told_roll : {M_PI, -M_PI, M_PI + 1 * kDeg, -M_PI - 1 * kDeg, roll + 1.5 * kDeg})
      {
        const FrameResult r = refined(depth, SensorPose{1.03, 16 * kDeg, told_roll});
        SCOPED_TRACE(::testing::Message() << "type " << type << " roll " << roll << " told " << told_roll);
        ASSERT_EQ(r.floor_fit.status, FloorFitStatus::kAccepted) << toString(r.floor_fit.status);
        EXPECT_NEAR(r.pose.height, truth.height, 0.0005);
        EXPECT_NEAR(r.pose.pitch, truth.pitch, 0.01 * kDeg);
        EXPECT_NEAR(wrapAngle(r.pose.roll - truth.roll), 0.0, 0.01 * kDeg);
        EXPECT_LE(std::fabs(r.pose.roll), M_PI);
        EXPECT_LE(std::fabs(r.floor_fit.applied.roll), 2.5 * kDeg);  // the short way round
      }
    }
}

TEST(FloorFit, AgreesWithAPlainLeastSquaresPlaneThroughItsPixels)
{
  // On a noisy floor without clutter the robust fit is a weighted least-squares fit: compare with cv::solve over
  // the same sampled pixels, weighted 1 / band^2, the plane e = a + b x + c y.
  const SensorPose truth{1.1, 15 * kDeg, 1 * kDeg};
  const cv::Mat depth = frameOf(Scene{}, truth, CV_16UC1, 3);
  Config cfg;
  Pipeline p(kinect(), cfg);
  FrameResult out;
  const SensorPose prior = told(truth, {0.03, 0.5, -0.5});
  p.process(depth, prior, out);
  ASSERT_TRUE(out.floor_fit.accepted());
  const std::vector<FloorFit::Point> pts = p.floorFit().points();
  ASSERT_GT(pts.size(), 500u);
  cv::Mat A(static_cast<int>(pts.size()), 3, CV_64F), rhs(static_cast<int>(pts.size()), 1, CV_64F);
  for (std::size_t i = 0; i < pts.size(); ++i)
  {
    const double w = 1.0 / pts[i].band;
    A.at<double>(i, 0) = w;
    A.at<double>(i, 1) = w * pts[i].x;
    A.at<double>(i, 2) = w * pts[i].y;
    rhs.at<double>(i) = w * pts[i].e;
  }
  cv::Mat sol;
  ASSERT_TRUE(cv::solve(A, rhs, sol, cv::DECOMP_SVD));
  // The prior's level frame: the learned correction was 0 before this first frame.
  const SensorPose ls = poseFromFloorPlane(prior, sol.at<double>(0) - prior.height, sol.at<double>(1), sol.at<double>(2));
  EXPECT_NEAR(out.pose.height, ls.height, 0.0005);
  EXPECT_NEAR(out.pose.pitch, ls.pitch, 0.01 * kDeg);
  EXPECT_NEAR(out.pose.roll, ls.roll, 0.01 * kDeg);
}

TEST(FloorFit, AFitBelowTheNoiseKeepsThePrior)
{
  // Told the true pose of a noisy floor: the fit lands within noise of it and the frame keeps the prior exactly.
  const SensorPose truth{1.1, 15 * kDeg, 0.5 * kDeg};
  for (const int type : {CV_8UC1, CV_16UC1, CV_32FC1})
  {
    const FrameResult r = refined(frameOf(Scene{}, truth, type, 8), truth);
    ASSERT_TRUE(r.floor_fit.accepted());
    EXPECT_LT(r.floor_fit.shift, 0.1);
    EXPECT_EQ(r.pose.height, truth.height);
    EXPECT_EQ(r.pose.pitch, truth.pitch);
    EXPECT_EQ(r.pose.roll, truth.roll);
    EXPECT_NE(r.floor_fit.fit.height, 0.0);  // the fit itself did move a little
  }
}

TEST(FloorFit, OffGivesThePriorExactly)
{
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  const cv::Mat depth = frameOf(Scene{}, truth, CV_16UC1, 3);
  Config cfg;
  cfg.refine_floor = false;
  const SensorPose prior = told(truth, {0.05, 1, 1});
  const FrameResult r = refined(depth, prior, cfg);
  EXPECT_EQ(r.floor_fit.status, FloorFitStatus::kOff);
  EXPECT_EQ(r.pose.height, prior.height);
  EXPECT_EQ(r.pose.pitch, prior.pitch);
  EXPECT_EQ(r.pose.roll, prior.roll);
}

TEST(FloorFit, DeclinesWithoutFloorAndKeepsThePrior)
{
  // A wall filling the view, and an image without any depth: nothing to fit.
  Scene wall;
  wall.floor = false;
  wall.boxes.push_back({0.8, 1.0, -5, 5, -1, 4});
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  const SensorPose prior = told(truth, {0.05, 1, 0});
  for (const cv::Mat& depth : {frameOf(wall, truth, CV_16UC1, 3), cv::Mat(cv::Mat::zeros(424, 512, CV_16UC1))})
  {
    const FrameResult r = refined(depth, prior);
    EXPECT_EQ(r.floor_fit.status, FloorFitStatus::kTooFewPixels);
    EXPECT_EQ(r.pose.height, prior.height);
    EXPECT_EQ(r.pose.pitch, prior.pitch);
  }
}

TEST(FloorFit, AcceptsBeyondItsBoundsOnlyWithClearSupportAndNeverBeyondTwice)
{
  // Bound 2 cm. Told 1.5 cm high: within the bound. Told 3 cm high: beyond it, but the whole floor supports the fit
  // (a rocking platform): accepted. Told 5 cm high: beyond twice the bound, declined whatever the support.
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  const cv::Mat depth = frameOf(Scene{}, truth, CV_16UC1, 3);
  Config cfg;
  cfg.floor_max_height_error = 0.02;
  EXPECT_TRUE(refined(depth, told(truth, {0.015, 0, 0}), cfg).floor_fit.accepted());
  const FrameResult beyond = refined(depth, told(truth, {0.03, 0, 0}), cfg);
  ASSERT_TRUE(beyond.floor_fit.accepted()) << toString(beyond.floor_fit.status);
  EXPECT_NEAR(beyond.pose.height, truth.height, 0.002);
  const FrameResult r = refined(depth, told(truth, {0.05, 0, 0}), cfg);
  EXPECT_NE(r.floor_fit.status, FloorFitStatus::kAccepted);
  EXPECT_EQ(r.pose.height, truth.height + 0.05);
  // Little floor in view (a strip the frame barely supports): beyond the bound is declined.
  Config strict = cfg;
  strict.floor_min_pixels = beyond.floor_fit.pixels * 2 / 3;
  const FrameResult weak = refined(depth, told(truth, {0.03, 0, 0}), strict);
  EXPECT_EQ(weak.floor_fit.status, FloorFitStatus::kOutOfBounds) << toString(weak.floor_fit.status);
}

TEST(FloorFit, DeclinesResidualsWiderThanTheNoise)
{
  // A floor seen through ten times the noise the threshold curve expects.
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  Rendering ren;
  renderScene(kinect(), truth.height, truth.pitch, truth.roll, Scene{}, ren);
  cv::Mat m = ren.depth.clone();
  addKinectNoise(m, 9, 0.03, 0.02, 0.0);
  const FrameResult r = refined(encodeDepth(m, CV_32FC1, 12.0), truth);
  EXPECT_EQ(r.floor_fit.status, FloorFitStatus::kSpreadTooLarge) << toString(r.floor_fit.status);
}

TEST(FloorFit, ANarrowStripOfFloorIsIllConditioned)
{
  // Only a strip of floor between a wall close ahead and the robot, seen over a few columns: the pitch is not
  // fixed by it (all its pixels lie at one distance).
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  Scene s;
  s.boxes.push_back({1.30, 1.5, -5, 5, 0.0, 3.0});
  cv::Mat depth = frameOf(s, truth, CV_32FC1, 0);
  // keep only rows where the floor meets the wall's foot, and columns in the middle
  cv::Mat masked(depth.size(), CV_32FC1, cv::Scalar(0));
  depth(cv::Rect(236, 0, 40, 424)).copyTo(masked(cv::Rect(236, 0, 40, 424)));
  Config cfg;
  cfg.floor_min_pixels = 100;
  const FrameResult r = refined(masked, told(truth, {0.0, 1.0, 0.0}), cfg);
  EXPECT_NE(r.floor_fit.status, FloorFitStatus::kAccepted)
      << toString(r.floor_fit.status) << " pitch " << (r.pose.pitch - truth.pitch) / kDeg << " deg off";
}

TEST(FloorFit, NeverTakesATableTopForTheFloor)
{
  // A bed-high and a table-high top filling half the view, a little floor around them, every told pose error: the
  // fitted floor is the floor (within a few millimetres) or the prior is kept, and every pixel of the top stays an
  // obstacle.
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  for (const double top : {0.45, 0.72})
  {
    Scene s;
    s.boxes.push_back({0.6, 3.0, -1.5, 1.5, top - 0.05, top});  // a slab: its top and edges are seen
    Rendering ren;
    renderScene(kinect(), truth.height, truth.pitch, truth.roll, s, ren);
    cv::Mat m = ren.depth.clone();
    addKinectNoise(m, 4);
    const cv::Mat depth = encodeDepth(m, CV_16UC1, 12.0);
    for (const Told& e : kErrors)
    {
      const FrameResult r = refined(depth, told(truth, e));
      SCOPED_TRACE(::testing::Message() << "top " << top << " m, error " << e.dh << "/" << e.dp << "/" << e.dr << ": "
                                        << toString(r.floor_fit.status));
      if (r.floor_fit.accepted())
      {
        EXPECT_NEAR(r.pose.height, truth.height, 0.01);
        EXPECT_NEAR(r.pose.pitch, truth.pitch, 0.2 * kDeg);
      }
      int top_pixels = 0, top_removed = 0;
      for (int v = 0; v < ren.object.rows; ++v)
        for (int u = 0; u < ren.object.cols; ++u)
          if (ren.object.at<std::int16_t>(v, u) == 10 && ren.height.at<float>(v, u) > top - 0.005f)
          {
            ++top_pixels;
            top_removed += r.labels.at<std::uint8_t>(v, u) != kKept;
          }
      ASSERT_GT(top_pixels, 10000);
      EXPECT_LE(top_removed, top_pixels / 1000);  // dropouts of the noise model only
    }
  }
}

TEST(FloorFit, KeepsTheFloorBesideAStairDown)
{
  // The floor ends 2.5 m ahead and the next level is 17 cm lower: the fit keeps the upper level.
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  Scene s;
  s.holes.push_back({2.5, 30.0, -30.0, 30.0, 0, 0});
  s.hole_depth = 0.17;
  const cv::Mat depth = frameOf(s, truth, CV_16UC1, 4);
  for (const Told& e : kErrors)
  {
    const FrameResult r = refined(depth, told(truth, e));
    ASSERT_TRUE(r.floor_fit.accepted()) << toString(r.floor_fit.status);
    EXPECT_NEAR(r.pose.height, truth.height, 0.002);
    EXPECT_NEAR(r.pose.pitch, truth.pitch, 0.05 * kDeg);
  }
}

TEST(FloorFit, LearnsAPersistentErrorWithItsTimeConstant)
{
  // Every frame told 4 cm too high, 30 Hz stamps: the first well-supported fit weighs far more than the prior (its
  // variance is tiny against the bound's), so the learned correction holds the error within the first frames;
  // then with no floor in view the frames are processed at the prior plus what was learned.
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  const cv::Mat floor = frameOf(Scene{}, truth, CV_16UC1, 5);
  Config cfg;
  cfg.floor_learn_time = 1.0;
  Pipeline p(kinect(), cfg);
  FrameResult out;
  const SensorPose prior = told(truth, {0.04, 0, 0});
  p.process(floor, prior, out, 100.0);
  ASSERT_TRUE(out.floor_fit.accepted());
  EXPECT_NEAR(p.floorFit().learned().height, -0.04, 0.004);
  for (int i = 1; i <= 30; ++i)
    p.process(floor, prior, out, 100.0 + i / 30.0);
  for (int i = 31; i <= 300; ++i)
    p.process(floor, prior, out, 100.0 + i / 30.0);
  // Learning stops once what is left moves the floor by less than a tenth of t(d) (3 mm near the robot).
  EXPECT_NEAR(p.floorFit().learned().height, -0.04, 0.004);
  EXPECT_LT(out.floor_fit.shift, 0.1);
  EXPECT_NEAR(out.floor_fit.applied.height, p.floorFit().learned().height, 1e-12);
  const cv::Mat nothing = cv::Mat::zeros(424, 512, CV_16UC1);
  p.process(nothing, prior, out, 110.1);
  EXPECT_EQ(out.floor_fit.status, FloorFitStatus::kTooFewPixels);
  EXPECT_NEAR(out.pose.height, truth.height, 0.004);
  p.reset();
  EXPECT_EQ(p.floorFit().learned().height, 0.0);
  p.process(nothing, prior, out, 110.2);
  EXPECT_EQ(out.pose.height, prior.height);
}

TEST(FloorFit, WithoutStampsFramesAreAThirtiethOfASecondApart)
{
  const SensorPose truth{1.1, 15 * kDeg, 0.0};
  const cv::Mat floor = frameOf(Scene{}, truth, CV_16UC1, 5);
  Config cfg;
  cfg.floor_learn_time = 1.0;
  Pipeline with(kinect(), cfg), without(kinect(), cfg);
  FrameResult out;
  const SensorPose prior = told(truth, {0.04, 0, 0});
  for (int i = 0; i < 20; ++i)
  {
    with.process(floor, prior, out, 5.0 + i / 30.0);
    without.process(floor, prior, out);
  }
  EXPECT_NEAR(with.floorFit().learned().height, without.floorFit().learned().height, 1e-9);
}

TEST(FloorFit, ConfigFieldsAreValidated)
{
  Config c;
  c.floor_max_height_error = 0.0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = Config();
  c.floor_max_pitch_error = std::nan("");
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = Config();
  c.floor_min_pixels = 0;
  EXPECT_THROW(c.validate(), std::invalid_argument);
  c = Config();
  c.floor_learn_time = -1.0;
  try
  {
    c.validate();
    FAIL() << "accepted floor_learn_time = -1";
  }
  catch (const std::invalid_argument& e)
  {
    EXPECT_NE(std::string(e.what()).find("floor_learn_time = -1"), std::string::npos) << e.what();
  }
}
