// The labelling by value thresholds (src/core/stages/labels/by_value.h, private to the core) against the reference
// labeller, the rule pixel by pixel (stages/labels/per_pixel.h), row by row: wherever it takes a row, the same labels,
// cleaned depths, counts and rescue, bit for bit. Rows at every rise from steeply down to up, whose values crowd around
// the floor band's two edges and the ceiling plane, with the rescue's raw values above the opened ones, for curves the
// proof holds for, one whose 1 cm cells make d - t dip (windowed), and one too steep for it; 8 and 16 bits.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include "kinect_pipeline/model/threshold_curve.h"
#include "stages/labels/by_value.h"
#include "stages/labels/per_pixel.h"
#include "stages/labels/rule.h"
#include "test_util.h"

using namespace kinect_pipeline;
using namespace kinect_pipeline::detail;

namespace
{
struct Tally
{
  int rows = 0, by_value = 0;
};

// A row of w values around v0 (spread values either side), a quarter of them anywhere, a few no-return.
template <typename T>
void sweep(std::mt19937& rng, double v0, double spread, int w, std::vector<T>& src, std::vector<T>& in, double move)
{
  constexpr int none = DepthTraits<T>::kNoReturn;
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int u = 0; u < w; ++u)
  {
    double v = unit(rng) < 0.25 ? 1.0 + unit(rng) * (none - 2) : v0 + (unit(rng) * 2.0 - 1.0) * spread;
    v = std::clamp(v, 1.0, static_cast<double>(none - 1));
    src[u] = unit(rng) < 0.02 ? static_cast<T>(none) : static_cast<T>(v);
    // The raw value: the opening only moves values nearer, here by up to move values; some unknown (0).
    const double raw = std::min(static_cast<double>(none - 1), src[u] + unit(rng) * move);
    in[u] = unit(rng) < 0.02 ? T(0) : (src[u] == none ? static_cast<T>(none) : static_cast<T>(raw));
  }
}

template <typename T>
void checkRows(const std::vector<CurvePoint>& curve, double max_depth, float floor_h, float ceil_h, Tally& tally)
{
  constexpr bool k8 = sizeof(T) == 1;
  constexpr int w = k8 ? 300 : 1200;
  ThresholdLut lut;
  lut.build(curve, k8 ? Encoding::kMono8 : Encoding::kMono16, max_depth);
  const float scale = k8 ? static_cast<float>(max_depth / 255.0) : 0.001f;
  const ValueTerms terms = valueTerms<T>(lut.valueTable(), scale);
  std::vector<float> col(w, 0.0f), row(1), t(w), fh(w);
  std::vector<std::int32_t> steps(w);
  std::vector<std::uint8_t> cand(w + 8), vlab(256), vdst(256), lab_v(w), lab_p(w);
  std::vector<T> src(w), in(w), dst_v(w), dst_p(w);
  const LabelBuffers buf{t.data(), fh.data(), steps.data(), cand.data(), vlab.data(), vdst.data()};
  std::mt19937 rng(17);
  for (int i = 0; i < 240; ++i)
  {
    // Rises from -1.2 (looking down steeply) to +0.4 (up), denser near 0 (the far floor).
    const double x = i / 239.0;
    const float rise = static_cast<float>(x < 0.75 ? -1.2 * std::pow(1.0 - x / 0.75, 3.0) - 1e-4 : (x - 0.75) * 1.6);
    row[0] = rise;
    const RuleTerms f{{scale, floor_h, ceil_h}, col.data(), row.data(), &lut};
    const ValueLabeller<T> value(f, terms, true);
    for (int e = 0; e < 3; ++e)  // the near edge, the far edge, and the ceiling plane or the floor itself
    {
      const double floor_at = rise < 0.0f ? floor_h / -rise : 0.0;
      const double tf = evaluateCurve(curve, std::min(floor_at, 60.0));
      const double d = rise < 0.0f ? (e == 0 ? floor_at - tf : e == 1 ? floor_at + tf : floor_at)
                                   : (rise > 0.0f ? ceil_h / rise : 3.0);
      sweep<T>(rng, d / scale, k8 ? 4.0 : 60.0, w, src, in, 2.5 * tf / scale);
      for (const bool opened : {true, false})
      {
        const T* raw = opened ? in.data() : nullptr;
        RowCounts cv;
        const bool taken = value.label(0, src.data(), raw, w, lab_v.data(), dst_v.data(), buf, cv);
        const RowCounts cp = labelRowByPixel<T>(f, 0, src.data(), raw, w, lab_p.data(), dst_p.data(), t.data(),
                                                fh.data(), steps.data(), cand.data());
        ++tally.rows;
        tally.by_value += taken;
        if (!taken)
          continue;
        const std::string where = std::string(k8 ? "8" : "16") + "-bit, max_depth " + std::to_string(max_depth) +
                                  ", rise " + std::to_string(rise) + ", edge " + std::to_string(e) +
                                  (opened ? ", opened" : "");
        int bad = 0;
        for (int u = 0; u < w; ++u)
          if ((lab_v[u] != lab_p[u] || dst_v[u] != dst_p[u]) && ++bad <= 3)
            ADD_FAILURE() << where << ": pixel " << u << " value " << double(src[u]) << " raw " << double(in[u])
                          << ": by value label " << int(lab_v[u]) << ", by pixel " << int(lab_p[u]);
        ASSERT_EQ(bad, 0) << where;
        ASSERT_EQ(cv.kept, cp.kept) << where;
        ASSERT_EQ(cv.invalid, cp.invalid) << where;
        ASSERT_EQ(cv.floor, cp.floor) << where;
        ASSERT_EQ(cv.ceiling, cp.ceiling) << where;
        // Where the labelling reports the first and last kept and below-floor pixels, they are those.
        for (const auto& [first, last, l] : {std::tuple{cv.kept_first, cv.kept_last, kKept},
                                             std::tuple{cv.below_first, cv.below_last, kBelowFloor}})
          if (first >= 0)
          {
            ASSERT_EQ(first, std::find(lab_p.begin(), lab_p.end(), l) - lab_p.begin()) << where;
            ASSERT_EQ(last, w - 1 - (std::find(lab_p.rbegin(), lab_p.rend(), l) - lab_p.rbegin())) << where;
          }
      }
    }
  }
}
}  // namespace

TEST(ValueLabelling, GivesTheRulesLabelsWhereverItTakesARow)
{
  const std::vector<std::vector<CurvePoint>> curves = {
      defaultThresholdCurve(), parseThresholdCurve("0.5:0.02, 12:3.0"),
      parseThresholdCurve("0.5:0.02, 6:0.05, 7:0.6, 12:0.7"),  // d - t falls by metres from 6 to 7 m
      parseThresholdCurve("0.5:0.2, 12:0.2")};
  Tally t8, t16;
  for (const auto& curve : curves)
    for (const double max_depth : {4.5, 12.0})
      for (const auto& [floor_h, ceil_h] : {std::pair{1.1f, 0.9f}, {0.25f, 2.0f}, {1.1f, -0.2f}})
      {
        checkRows<std::uint8_t>(curve, max_depth, floor_h, ceil_h, t8);
        checkRows<std::uint16_t>(curve, max_depth, floor_h, ceil_h, t16);
        if (HasFatalFailure())
          return;
      }
  // Both ways are taken: many rows by value (28392 and 19044 of 34560 when this was written), and some not (the
  // steep curve's, a ceiling plane below the sensor).
  RecordProperty("rows_8bit", std::to_string(t8.by_value) + " of " + std::to_string(t8.rows) + " by value");
  RecordProperty("rows_16bit", std::to_string(t16.by_value) + " of " + std::to_string(t16.rows) + " by value");
  for (const Tally& t : {t8, t16})
  {
    EXPECT_GT(t.by_value, t.rows / 4) << "of " << t.rows << " rows";
    EXPECT_LT(t.by_value, t.rows) << "of " << t.rows << " rows";
  }
}

// The per-pixel labeller's floor offsets under a floor profile (liftRow: steps, then a gather; liftRowByRuns: runs of
// one step, bisected; liftRowByLookup: a lookup in a vector of the row's offsets, on every SIMD target) are the
// rule's own, PlaneRule::floorAt, bit for bit: rows of every slope (roll either way), rises from below the table to
// above 0, and column terms that are not straight (monotone still). The runs decline a row of 16 steps or more, the
// lookup a row of as many steps as its vectors have float lanes or more (nothing written), and each takes the others.
TEST(FloorLift, LiftRowIsFloorAtPixelByPixel)
{
  std::vector<float> table(256);
  for (int i = 0; i < 256; ++i)
    table[i] = 0.001f * static_cast<float>((i * 37) % 41) - 0.02f;
  PlaneRule rule{0.001f, 1.1f, 1.0f, FloorLift{table.data(), -0.9f, 256 / 0.9f, 255}};
  const int w = 640;
  std::vector<float> col(w), fh(w), runs(w), looked(w);
  std::vector<std::int32_t> steps(w);
  kp_test::forEachSimdTarget([&](const std::string& target) {
    int by_runs = 0, by_lookup = 0, rows = 0, narrow = 0;
    for (const bool cubic : {false, true})
      for (const float slope : {-3e-4f, -7e-5f, -1e-5f, -1e-7f, 0.0f, 2e-5f, 5e-5f, 8e-5f, 4e-4f})
        for (const float rise_row : {-1.2f, -0.9f, -0.6f, -0.3001f, -0.05f, 0.0f, 0.3f})
        {
          for (int u = 0; u < w; ++u)
          {
            const float x = static_cast<float>(u - w / 2);
            col[u] = cubic ? slope * x * x * x / static_cast<float>(w * w / 4) : slope * x;
          }
          SCOPED_TRACE(target + (cubic ? ", cubic, slope " : ", slope ") + std::to_string(slope) + ", rise_row " +
                       std::to_string(rise_row));
          liftRow(col.data(), rise_row, rule, w, steps.data(), fh.data());
          std::fill(runs.begin(), runs.end(), -7.0f);
          std::fill(looked.begin(), looked.end(), -7.0f);
          const bool ran = liftRowByRuns(col.data(), rise_row, rule, w, runs.data());
          const bool looked_up = liftRowByLookup(col.data(), rise_row, rule, w, steps.data(), looked.data());
          const int crossed = std::abs(rule.lift.step(col[w - 1] + rise_row) - rule.lift.step(col[0] + rise_row));
          EXPECT_EQ(ran, crossed < 16);
          by_runs += ran, by_lookup += looked_up, ++rows, narrow += crossed < 4;
          for (int u = 0; u < w; ++u)
          {
            ASSERT_EQ(fh[u], rule.floorAt(col[u] + rise_row)) << "u " << u;
            ASSERT_EQ(runs[u], ran ? fh[u] : -7.0f) << "u " << u;
            ASSERT_EQ(looked[u], looked_up ? fh[u] : -7.0f) << "u " << u;
          }
        }
    EXPECT_GT(by_runs, rows / 3) << target;
    EXPECT_LT(by_runs, rows) << target;
    // Rows of up to 3 steps fit every target's vectors but the one-lane scalar target's.
    EXPECT_GE(by_lookup, target == "scalar" ? 1 : narrow) << target;
    EXPECT_LT(by_lookup, rows) << target;
    std::cout << "[ info ] " << target << ": " << by_lookup << " of " << rows << " rows by lookup, " << by_runs
              << " by runs\n";
  });
}

namespace
{
// A row's thresholds by the gather kernel and by the plain loop, against thresholdOf pixel by pixel, bit for bit.
template <typename T>
int expectGatherIsPlainLoop(const std::vector<T>& row, const ThresholdLut& lut, float scale, const std::string& where)
{
  const int w = static_cast<int>(row.size());
  std::vector<float> gathered(w, -1.0f), plain(w, -2.0f);
  rowThresholds(row.data(), lut, scale, w, gathered.data(), true);
  rowThresholds(row.data(), lut, scale, w, plain.data(), false);
  int bad = 0;
  for (int u = 0; u < w; ++u)
  {
    const float want = thresholdOf(lut, row[u], scale);
    if ((std::memcmp(&gathered[u], &want, 4) != 0 || std::memcmp(&plain[u], &want, 4) != 0) && ++bad <= 3)
      ADD_FAILURE() << where << ": pixel " << u << " value " << double(row[u]) << ": gather " << gathered[u]
                    << ", plain " << plain[u] << ", thresholdOf " << want;
  }
  return bad;
}
}  // namespace

namespace
{
// A row of n values from 0 to top in runs that climb slowly (a vector's cells within its lanes: the window's
// lookup) broken by jumps anywhere in 0..top (the gather), seeded.
template <typename T>
std::vector<T> runsAndJumps(std::size_t n, double top, unsigned seed)
{
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> any(0.0, top), step(0.0, top / 2000.0);
  std::vector<T> row(n);
  double v = any(rng);
  for (auto& x : row)
  {
    v = rng() % 23 == 0 ? any(rng) : std::min(top, v + step(rng));
    x = static_cast<T>(v);
  }
  return row;
}
}  // namespace

// The pixels' thresholds by the vector kernel (rowThresholds, gather on: 8 float lanes or more; a lookup within one
// vector of the table or the CPU's gather) are the plain loop's on every SIMD target this CPU has: every 8-bit value,
// every 16-bit one, float depths at and around every cell border, beyond the table, negative, 0, NaN and the
// infinities (forDepth's clamps), and rows of slow runs and jumps, in rows of whole vectors and not.
TEST(Thresholds, TheVectorKernelGivesThePlainLoopsBitsOnEveryTarget)
{
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<std::uint8_t> v8(256);
  for (int v = 0; v < 256; ++v)
    v8[v] = static_cast<std::uint8_t>(v);
  std::vector<std::uint16_t> v16(65536);
  for (int v = 0; v < 65536; ++v)
    v16[v] = static_cast<std::uint16_t>(v);
  std::vector<float> vf = {std::numeric_limits<float>::quiet_NaN(), -inf, inf, -1.0f, -0.0f, 0.0f, 1e-30f, 1e30f,
                           std::numeric_limits<float>::max(), std::numeric_limits<float>::denorm_min()};
  for (int cell = 0; cell <= 1300; ++cell)
  {
    const float border = static_cast<float>(cell) / ThresholdLut::kCellsPerMetre;
    vf.insert(vf.end(), {std::nextafter(border, -inf), border, std::nextafter(border, inf), border + 0.005f});
  }
  int bad = 0;
  const auto ran = kp_test::forEachSimdTarget([&](const std::string& target) {
    for (const double max_depth : {4.5, 12.0})
    {
      ThresholdLut l8, l16, lf;
      l8.build(defaultThresholdCurve(), Encoding::kMono8, max_depth);
      l16.build(defaultThresholdCurve(), Encoding::kMono16, max_depth);
      lf.build(defaultThresholdCurve(), Encoding::kFloat32, max_depth);
      const std::string where = target + ", max_depth " + std::to_string(max_depth);
      for (const std::size_t w : {std::size_t{5}, std::size_t{100}, std::size_t{512}})
        bad += expectGatherIsPlainLoop(std::vector<std::uint8_t>(v8.begin(), v8.begin() + std::min(w, v8.size())),
                                       l8, static_cast<float>(max_depth / 255.0), where + ", 8-bit");
      bad += expectGatherIsPlainLoop(v8, l8, static_cast<float>(max_depth / 255.0), where + ", 8-bit");
      bad += expectGatherIsPlainLoop(v16, l16, 0.001f, where + ", 16-bit");
      bad += expectGatherIsPlainLoop(vf, lf, 1.0f, where + ", float");
      bad += expectGatherIsPlainLoop(std::vector<float>(vf.begin(), vf.begin() + 13), lf, 1.0f, where + ", float");
      for (const unsigned seed : {1u, 2u, 3u})
      {
        bad += expectGatherIsPlainLoop(runsAndJumps<std::uint8_t>(512, 255.0, seed), l8,
                                       static_cast<float>(max_depth / 255.0), where + ", 8-bit runs");
        bad += expectGatherIsPlainLoop(runsAndJumps<std::uint16_t>(517, 20000.0, seed), l16, 0.001f,
                                       where + ", 16-bit runs");
        bad += expectGatherIsPlainLoop(runsAndJumps<float>(509, 20.0, seed), lf, 1.0f, where + ", float runs");
      }
    }
  });
  EXPECT_EQ(bad, 0);
  EXPECT_GE(ran.size(), 2u);
}
