#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

#include "kinect_pipeline/stages/scan.h"
#include "test_util.h"

using namespace kinect_pipeline;

namespace
{
constexpr float kInf = std::numeric_limits<float>::infinity();
}

TEST(FastAtan2, MatchesStdAtan2InAllQuadrants)
{
  double worst = 0.0;
  for (double a = -M_PI; a <= M_PI; a += 0.0007)
    for (double r : {1e-3, 1.0, 250.0})
    {
      const float x = static_cast<float>(r * std::cos(a)), y = static_cast<float>(r * std::sin(a));
      worst = std::max(worst, std::fabs(static_cast<double>(fastAtan2(y, x)) - std::atan2(y, x)));
    }
  EXPECT_LT(worst, 1e-5);
  EXPECT_EQ(fastAtan2(0.0f, 0.0f), 0.0f);
}

// The conversions towards zero that stand in for std::floor and std::ceil (binKey; the scalar target's crossings):
// exact at integers, halves, the floats next to integers and either sign, across the columns' range and beyond.
TEST(FloorToInt, IsStdFloorAndCeilOfEveryFiniteFloatTried)
{
  std::vector<float> xs = {0.0f, -0.0f, 0.5f, -0.5f, 1.0f, -1.0f, 2047.5f, -2.5f, 1e9f, -1e9f};
  for (int i = -3000; i <= 3000; ++i)
  {
    const float f = static_cast<float>(i) / 4.0f;  // integers, quarters and halves
    xs.insert(xs.end(), {f, std::nextafter(f, 1e30f), std::nextafter(f, -1e30f)});
  }
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> any(-1e6f, 1e6f);
  for (int i = 0; i < 100000; ++i)
    xs.push_back(any(rng));
  for (const float x : xs)
  {
    ASSERT_EQ(kinect_pipeline::floorToInt(x), static_cast<std::int32_t>(std::floor(x))) << x;
    ASSERT_EQ(kinect_pipeline::ceilToInt(x), static_cast<std::int32_t>(std::ceil(x))) << x;
  }
}

TEST(ScanProjector, ColumnBinsAreTheImageColumnsAtDefaults)
{
  const Camera cam = Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180);
  Config cfg;
  cfg.projection = Projection::kColumn;
  cfg.geometry = Geometry::kThesis;
  ScanProjector p;
  p.configure(cam, cfg);
  EXPECT_EQ(p.beams(), 512);
  EXPECT_NEAR(p.angleIncrement(), 70.6 * M_PI / 180 / 512, 1e-7);
  // Thesis eq 4.21 is linear in the column: every column's edges fall on bin boundaries, right to left.
  std::vector<float> buf(513);
  const float* fb = p.rowEdgeBins(0, buf.data());
  for (int e = 0; e <= 512; ++e)
    EXPECT_NEAR(fb[e], 512 - e, 1e-3) << e;
  // eq 4.21 puts angle 0 on column w/2 = 256, half a pixel right of the image centre: the scan is shifted.
  EXPECT_NEAR(p.angleMax() + p.angleMin(), p.angleIncrement(), 1e-6);
}

TEST(ScanProjector, HorizontalEdgesAreMonotoneAndCoverTheScan)
{
  const Camera cam = Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180);
  Config cfg;
  ScanProjector p;
  p.configure(cam, cfg);
  for (double pitch : {0.0, 0.26, 0.6})
  {
    p.setPose(pitch, 0.035);
    std::vector<float> buf(513);
    for (int r = 0; r < 424; r += 9)
    {
      const float* fb = p.rowEdgeBins(r, buf.data());
      for (int e = 1; e <= 512; ++e)
        ASSERT_LT(fb[e], fb[e - 1]) << "row " << r << " edge " << e;  // angle decreases to the right
    }
    float lo, hi;
    p.coverage(lo, hi);
    EXPECT_LE(lo, 0.5f);
    EXPECT_GE(hi, 511.5f);
  }
}

TEST(Confidence, RollingMeanWithAbsoluteValue)
{
  Config cfg;
  cfg.confidence_window = 3;
  cfg.confidence_distance = 0.5;
  Confidence c;
  c.configure(1, cfg);
  std::vector<float> r, i;
  auto push = [&](float d) {
    r = {d};
    c.apply(r, i);
    return i[0];
  };
  EXPECT_FLOAT_EQ(push(2.0f), 1.0f);                 // first sight: mean = itself
  EXPECT_FLOAT_EQ(push(2.0f), 1.0f);
  EXPECT_NEAR(push(2.6f), 1.0f - 0.4f / 0.5f, 1e-5);  // mean(2, 2, 2.6) = 2.2, |2.6 - 2.2| = 0.4
  EXPECT_NEAR(push(1.8f), 1.0f - (6.4f / 3.0f - 1.8f) / 0.5f, 1e-5);  // window (2, 2.6, 1.8): oldest 2 gone
  EXPECT_FLOAT_EQ(push(0.2f), 0.0f);                 // clamped at 0, never negative
}

TEST(Confidence, BeamAppearingOutOfInfinityIsTrustedAndNonFiniteHandled)
{
  Config cfg;
  cfg.confidence_window = 4;
  cfg.confidence_distance = 0.3;
  cfg.intensity_filter = true;
  cfg.min_intensity = 0.2;
  Confidence c;
  c.configure(3, cfg);
  std::vector<float> r = {kInf, kInf, kInf}, i;
  c.apply(r, i);
  EXPECT_EQ(i, (std::vector<float>{1.0f, 1.0f, 1.0f}));
  r = {1.5f, -kInf, std::numeric_limits<float>::quiet_NaN()};
  c.apply(r, i);
  EXPECT_FLOAT_EQ(i[0], 1.0f);  // the window's only finite range is this one
  EXPECT_FLOAT_EQ(r[0], 1.5f);  // so the filter keeps it
  EXPECT_FLOAT_EQ(i[1], 1.0f);
  EXPECT_FLOAT_EQ(i[2], 0.0f);
  EXPECT_TRUE(std::isinf(r[1]));
  // A jump far from the beam's mean is filtered to NaN; the +Inf beams are never filtered.
  r = {0.5f, kInf, kInf};
  c.apply(r, i);
  EXPECT_LE(i[0], 0.2f);
  EXPECT_TRUE(std::isnan(r[0]));
  EXPECT_TRUE(std::isinf(r[1]));
}

TEST(Confidence, WithoutFilterRangesAreUntouched)
{
  Config cfg;
  Confidence c;
  c.configure(2, cfg);
  std::vector<float> r = {1.0f, 2.0f}, i;
  c.apply(r, i);
  r = {5.0f, 2.0f};
  c.apply(r, i);
  EXPECT_FLOAT_EQ(r[0], 5.0f);
  EXPECT_FLOAT_EQ(i[0], 0.0f);
  c.reset();
  c.apply(r, i);
  EXPECT_FLOAT_EQ(i[0], 1.0f);
}

namespace
{
struct SpanCounts
{
  int rows = 0, up_rows = 0, checked_centres = 0, checked_gaps = 0;
};

// spanPixels of every 7th row of a pose against each pixel centre's bearing in double precision (see below).
// forward: every row must be binned from the bins' side (a forward-looking view); else rows it declines are skipped.
void checkSpanPixels(const Camera& cam, const Config& cfg, double pitch, double roll, bool forward, SpanCounts& c)
{
  ScanProjector p;
  p.configure(cam, cfg);
  p.setPose(pitch, roll);
  const int nb = p.beams();
  const double lo_angle = p.angleMin() - 0.5 * p.angleIncrement();
  std::vector<std::int32_t> lo(nb), hi(nb);
  const double sp = std::sin(pitch), cp = std::cos(pitch), sr = std::sin(roll), cr = std::cos(roll);
  for (int i = 0; i < 3 * cam.height; i += 7)
  {
    // Spans of varying ends across the middle, and of the left and right third (one side of a row that looks
    // behind the sensor, where the bearing grows with the column).
    const int r = i % cam.height, side = i / cam.height;
    const int a = side == 0 ? (r * 37) % 100 : (side == 1 ? 0 : 2 * cam.width / 3);
    const int b = side == 0 ? cam.width - 1 - (r * 13) % 90 : (side == 1 ? cam.width / 3 : cam.width - 1);
    int first = -1;
    const int n = p.spanPixels(r, a, b, lo.data(), hi.data(), first);
    if (forward)
      ASSERT_GE(n, 0) << "a forward-looking row has monotone bearings: pitch " << pitch << " roll " << roll;
    if (n <= 0)
      continue;
    SpanPlan plan;
    p.spanPlan(r, a, b, plan);
    c.up_rows += plan.up;
    ++c.rows;
    // Exact fractional bin position of centre u (the ray rotated by roll, then pitch; see PlaneModel).
    const double yn = (r - cam.cy) / cam.fy;
    auto pos = [&](int u) {
      const double xn = (u - cam.cx) / cam.fx;
      const double X = -sp * sr * xn + cp - sp * cr * yn, Y = -cr * xn + sr * yn;
      return (std::atan2(Y, X) - lo_angle) / p.angleIncrement();
    };
    for (int u = a; u <= b; ++u)
    {
      const double f = pos(u);
      const int k = static_cast<int>(std::floor(f));
      if (k < 0 || k >= nb || std::fabs(f - std::round(f)) < 1e-3)
        continue;
      ASSERT_TRUE(k >= first && k < first + n) << "centre " << u << " in bin " << k << " outside the bins";
      EXPECT_TRUE(lo[k - first] <= u && u <= hi[k - first])
          << "row " << r << " centre " << u << " (bin position " << f << ") not in bin " << k << "'s pixels "
          << lo[k - first] << ".." << hi[k - first];
      ++c.checked_centres;
    }
    for (int u = a; u < b; ++u)
    {
      const double f0 = pos(u), f1 = pos(u + 1);
      if (std::fabs(f1 - f0) > 0.5 * nb)
        continue;  // the two straddle the direction straight behind (the scan's two ends)
      for (int k = static_cast<int>(std::floor(std::min(f0, f1))) + 1;
           k < static_cast<int>(std::floor(std::max(f0, f1))); ++k)
      {
        // Bin k holds no centre: it goes to the nearer of u, u + 1 (clear cases only).
        const double mid = 0.5 * (f0 + f1);
        if (k < 0 || k >= nb || std::fabs(k + 0.5 - mid) < 0.05)
          continue;
        const int want = (k + 0.5 < mid) == (f0 < f1) ? u : u + 1;
        ASSERT_TRUE(k >= first && k < first + n);
        EXPECT_EQ(lo[k - first], want) << "row " << r << " gap bin " << k;
        EXPECT_EQ(hi[k - first], want) << "row " << r << " gap bin " << k;
        ++c.checked_gaps;
      }
    }
    // Bins before and after the span's pixels get nothing of it.
    for (int j = 0; j < n; ++j)
      EXPECT_TRUE(lo[j] > hi[j] || (a <= lo[j] && hi[j] <= b));
  }
}
}  // namespace

// spanPixels (the pipeline's binning of the horizontal projection, from the bins' side) against each pixel
// centre's bearing in double precision: every centre clear of a border lies in its bin's pixels, and every bin
// between two centres clear of its middle gets the nearer centre.
TEST(ScanProjector, SpanPixelsAreTheCentresOfEachBin)
{
  const Camera cam = Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180);
  SpanCounts c;
  for (int beams : {0, 200, 900})
    for (double pitch : {0.0, 0.26, 0.7, -0.3})
      for (double roll : {0.0, 0.05, -0.3})
      {
        Config cfg;
        cfg.scan_beams = beams;
        checkSpanPixels(cam, cfg, pitch, roll, true, c);
      }
  EXPECT_GT(c.checked_centres, 100000);
  EXPECT_GT(c.checked_gaps, 1000);  // beams = 900: bins narrower than a pixel
  EXPECT_GT(c.rows, 500);
}

// The same, looking steeply down with a scan all round: the lowest rows look behind the sensor, where the bearing
// grows with the column (SpanPlan::up), the crossings' other direction.
TEST(ScanProjector, SpanPixelsAreTheCentresOfEachBinBehindTheSensor)
{
  const Camera cam = Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180);
  SpanCounts c;
  for (int beams : {400, 2000, 6000})
    for (double pitch : {1.2, 1.35, 1.5})
      for (double roll : {0.0, 0.05, -0.3})
      {
        Config cfg;
        cfg.scan_beams = beams;
        cfg.scan_fov = 2.0 * M_PI;
        checkSpanPixels(cam, cfg, pitch, roll, false, c);
      }
  EXPECT_GT(c.up_rows, 50);
  EXPECT_GT(c.checked_centres, 50000);
  EXPECT_GT(c.checked_gaps, 1000);  // 6000 beams all round: bins narrower than a pixel
}

TEST(ScanProjector, SpanPixelsDeclinesRowsThatLookStraightDown)
{
  const Camera cam = Camera::fromFov(512, 424, 70.6 * M_PI / 180, 60 * M_PI / 180);
  Config cfg;
  ScanProjector p;
  p.configure(cam, cfg);
  p.setPose(M_PI / 2, 0.0);  // the optical axis points down: the middle row's rays pass under the sensor
  std::vector<std::int32_t> lo(p.beams()), hi(p.beams());
  int first = 0;
  EXPECT_EQ(p.spanPixels(212, 0, 511, lo.data(), hi.data(), first), -1);
  cfg.projection = Projection::kColumn;
  p.configure(cam, cfg);
  EXPECT_EQ(p.spanPixels(0, 0, 511, lo.data(), hi.data(), first), -1);
}

// detail::pullNearest on every SIMD target against nearestOf's plain loop, bin by bin: plans of bins narrower and
// wider than a pixel (pairs, single pixels, empty bins clipped at the span's ends, bins of many pixels), growing and
// falling, of every length around the vector widths, over ranges with NaN and +Inf, with counts and without.
TEST(ScanPull, EveryTargetGivesThePlainLoopsBins)
{
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  int bins_checked = 0;
  const auto ran = kp_test::forEachSimdTarget([&](const std::string& target) {
    for (int trial = 0; trial < 400; ++trial)
    {
      const int n = 1 + trial % 70;
      const float width = trial % 3 == 0 ? 0.4f : (trial % 3 == 1 ? 1.1f : 3.0f);  // pixels per bin (mean)
      std::vector<float> g(n + 1);  // the borders' columns, growing
      g[0] = 3.0f + 2.0f * unit(rng);
      for (int j = 1; j <= n; ++j)
        g[j] = g[j - 1] + width * (0.2f + 1.6f * unit(rng));
      const int a = static_cast<int>(g[0]) + 1, b = static_cast<int>(g[n]) - 1;  // clipped: end bins may be empty
      std::vector<std::int32_t> lo(n), hi(n);
      for (int j = 0; j < n; ++j)
      {
        int l = static_cast<int>(std::ceil(g[j])), h = static_cast<int>(std::ceil(g[j + 1])) - 1;
        if (l > h)
          l = h = static_cast<int>(std::floor(0.5f * (g[j] + g[j + 1]) + 0.5f));
        lo[j] = std::max(l, a);
        hi[j] = std::min(h, b);
      }
      if (trial % 2 == 1)  // falling
      {
        std::reverse(lo.begin(), lo.end());
        std::reverse(hi.begin(), hi.end());
      }
      std::vector<float> range(static_cast<std::size_t>(g[n]) + 40);
      for (float& r : range)
      {
        const float x = unit(rng);
        r = x < 0.05f ? std::nanf("") : (x < 0.15f ? kInf : 0.5f + 8.0f * unit(rng));
      }
      std::vector<float> start(n);
      for (float& s : start)
        s = unit(rng) < 0.3f ? kInf : 0.5f + 8.0f * unit(rng);
      for (const bool count : {false, true})
      {
        std::vector<float> bins = start, want = start;
        std::vector<std::int32_t> counts(n, 1), want_counts(n, 1);
        detail::pullNearest(range.data(), lo.data(), hi.data(), n, bins.data(), count ? counts.data() : nullptr);
        for (int j = 0; j < n; ++j)
        {
          float v = kInf;
          for (int u = lo[j]; u <= hi[j]; ++u)
          {
            v = range[u] < v ? range[u] : v;
            want_counts[j] += range[u] < kInf;
          }
          want[j] = v < want[j] ? v : want[j];
        }
        ASSERT_EQ(0, std::memcmp(bins.data(), want.data(), n * sizeof(float)))
            << target << ", trial " << trial << ", counts " << count;
        if (count)
          ASSERT_EQ(counts, want_counts) << target << ", trial " << trial;
        bins_checked += n;
      }
    }
  });
  EXPECT_GE(ran.size(), 2u);
  EXPECT_GT(bins_checked, 20000 * static_cast<int>(ran.size()));
}
