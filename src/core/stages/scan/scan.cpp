// ScanProjector (stages/scan.h): the geometry of the scan binning, bins of pixel centres and of the bins' border
// crossings, and the scan's SIMD kernels (stages/scan/scan_kernels.h), compiled once per target. Design notes:
// docs/core_design.md ("The scan"; "SIMD kernels and their references").
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "stages/scan/scan.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "kinect_pipeline/stages/scan.h"

#include "base/simd.h"
#include "stages/scan/scan_kernels.h"

#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/model/pose.h"

#include <algorithm>
#include <cmath>
#include <limits>

HWY_BEFORE_NAMESPACE();
namespace kinect_pipeline
{
namespace detail
{
namespace HWY_NAMESPACE
{
namespace hn = hwy::HWY_NAMESPACE;
namespace
{
// Restrict parameters of a small function: the loops vectorise without a runtime alias check.
void edgeBinLoop(const float* __restrict xe, int e0, int e1, float ax, float ay, float bx, float by, float lo,
                 float inv, float* __restrict out)
{
  for (int e = e0; e <= e1; ++e)
    out[e] = rayBin(xe[e], ax, ay, bx, by, lo, inv);
}

// Range per metre of depth of the ray (x, y) of the horizontal projection, times the depth z.
__attribute__((always_inline)) inline float rayRange(float x, float y, float z) { return z * std::sqrt(x * x + y * y); }

// The horizontal projection's: bin position (as edgeBinLoop for edges), bin and range of each pixel centre.
void spanLoop(const float* __restrict xn, int u0, int u1, float ax, float ay, float bx, float by, float lo,
              float inv, float beams, const float* __restrict z, float* __restrict fb,
              std::int32_t* __restrict key, float* __restrict range)
{
  for (int u = u0; u <= u1; ++u)
  {
    const float x = ax * xn[u] + bx, y = ay * xn[u] + by;
    const float f = rayBin(xn[u], ax, ay, bx, by, lo, inv);
    fb[u] = f;
    key[u] = binKey(f, beams);
    range[u] = rayRange(x, y, z[u]);
  }
}

void rangeLoop(const float* __restrict xn, int u0, int u1, float ax, float ay, float bx, float by,
               const float* __restrict z, float* __restrict range)
{
  for (int u = u0; u <= u1; ++u)
    range[u] = rayRange(ax * xn[u] + bx, ay * xn[u] + by, z[u]);
}

// The squared ranges of a cleaned row: (depth of each kept pixel, +Inf for removed ones)^2 (X^2 + Y^2). No square
// root per pixel: the nearest squared range of a bin is the square of its nearest range, rooted once per beam.
template <typename T>
void keptRangeLoop(const float* __restrict xn, int u0, int u1, float ax, float ay, float bx, float by,
                   const T* __restrict row, float scale, float* __restrict range)
{
  overlappedBlocks<32>(u0, u1 - u0 + 1, [&](int s, int n) {
    for (int u = s; u < s + n; ++u)
    {
      const float z = keptMetres(row[u], scale);
      const float x = ax * xn[u] + bx, y = ay * xn[u] + by;
      range[u] = (z * z) * (x * x + y * y);
    }
  });
}

// keptRangeLoop of a row without roll (ax = 0, ay = -1, by = 0): X = 0 xn + bx = bx and Y = -xn exactly, so
// X^2 + Y^2 = bx^2 + xn^2 with xn^2 from a table: the same bits with two operations fewer per pixel.
template <typename T>
void keptRangeLoopLevel(const float* __restrict xn2, int u0, int u1, float bx, const T* __restrict row,
                        float scale, float* __restrict range)
{
  const float bx2 = bx * bx;
  overlappedBlocks<32>(u0, u1 - u0 + 1, [&](int s, int n) {
    for (int u = s; u < s + n; ++u)
    {
      const float z = keptMetres(row[u], scale);
      range[u] = (z * z) * (bx2 + xn2[u]);
    }
  });
}

// A column position clamped to [lo, hi] (NaN to lo).
__attribute__((always_inline)) inline float clampIn(float g, float lo, float hi)
{
  g = g > lo ? g : lo;
  return g < hi ? g : hi;
}

// std::ceil and std::floor of a column position (finite, clamped), as the rounding instruction of every target but
// the scalar one, whose x86-64 baseline has none: there a library call per bin that kept pixelLoop from vectorising
// (47 % of a frame), so the conversion towards zero (ceilToInt, floorToInt; frames 40 % faster). On AVX2 and
// AVX-512 the instruction is 2-5 % faster.
HWY_INLINE float roundUp(float g)
{
  return HWY_TARGET == HWY_SCALAR ? static_cast<float>(ceilToInt(g)) : std::ceil(g);
}
HWY_INLINE float roundDown(float g)
{
  return HWY_TARGET == HWY_SCALAR ? static_cast<float>(floorToInt(g)) : std::floor(g);
}

// Pixels of each bin j < n from the columns where its borders j, j + 1 cross the row (crossing(), border terms
// p[j], q[j]), clipped to a..b. Bearings grow with the column (up): centres g0 <= u < g1; fall: g1 < u <= g0. A
// bin with no centre (narrower than a pixel) gets the centre nearest to its middle, taken halfway between the
// border crossings (the bearing's curvature over a pixel moves it by far less than a pixel).
template <bool kUp, bool kRoll>
void pixelLoop(const float* __restrict p, const float* __restrict q, int n, float bx, float by, float cx,
               int a, int b, std::int32_t* __restrict lo, std::int32_t* __restrict hi)
{
  const float gl = static_cast<float>(a) - 2.0f, gh = static_cast<float>(b) + 2.0f;
  overlappedBlocks<32>(0, n, [&](int s, int m) {
    for (int j = s; j < s + m; ++j)
    {
      const float g0 = clampIn(crossing<kRoll>(p[j], q[j], bx, by, cx), gl, gh);
      const float g1 = clampIn(crossing<kRoll>(p[j + 1], q[j + 1], bx, by, cx), gl, gh);
      // The middle's centre, floor(x) for x = 0.5 (g0 + g1) + 0.5, is needed for empty bins only: both crossings
      // then lie within one pixel spacing (up: (C - 1, C], C = ceil(g0); fall: [F, F + 1), F = floor(g0)), so
      // floor(x) is C - 1 or C (F or F + 1) and one compare with C (F + 1) finds it, without rounding x.
      const float x = 0.5f * (g0 + g1) + 0.5f;
      std::int32_t l, h, mid;
      if constexpr (kUp)
      {
        const float c0 = roundUp(g0);
        l = static_cast<std::int32_t>(c0);
        h = static_cast<std::int32_t>(roundUp(g1)) - 1;
        mid = l - 1 + (x >= c0);
      }
      else
      {
        const float f0 = roundDown(g0);
        l = static_cast<std::int32_t>(roundDown(g1)) + 1;
        h = static_cast<std::int32_t>(f0);
        mid = h + (x >= f0 + 1.0f);
      }
      const bool empty = l > h;
      l = empty ? mid : l;
      h = empty ? mid : h;
      lo[j] = l < a ? a : l;
      hi[j] = h > b ? b : h;
    }
  });
}


// The nearest of range[l..h] (+Inf if l > h); NaN ranges are ignored (a min that keeps the nearest so far). With
// count, *count also gains the number of finite ranges among them.
inline float nearestOf(const float* range, int l, int h, std::int32_t* count)
{
  float v = std::numeric_limits<float>::infinity();
  for (int u = l; u <= h; ++u)
  {
    v = range[u] < v ? range[u] : v;
    if (count)
      *count += range[u] < std::numeric_limits<float>::infinity();
  }
  return v;
}

// x < v ? x : v per lane (NaN in x: v), as nearestOf keeps the nearest so far; the x86 vector min is exactly that
// (Highway's scalar and emulated targets return the other operand where one is NaN, ARM's min NaN).
template <class V>
HWY_INLINE V nearer(V x, V v)
{
#if HWY_TARGET == HWY_SSE4 || HWY_TARGET == HWY_AVX2 || HWY_TARGET == HWY_AVX3
  return hn::Min(x, v);
#else
  return hn::IfThenElse(hn::Lt(x, v), x, v);
#endif
}

// Lane i of the 2N ranges w0, w1 (i < 2N; the lookups take i mod N).
template <class DF, class VF, class VI>
HWY_INLINE VF lookup2(DF df, VF w0, VF w1, VI i)
{
#if HWY_TARGET == HWY_AVX3
  (void)df;
  return VF{_mm512_permutex2var_ps(w0.raw, i.raw, w1.raw)};  // one instruction: Highway 1.0 has no two-table lookup
#else
  const hn::RebindToSigned<DF> di;
  const auto n = hn::Set(di, static_cast<std::int32_t>(hn::Lanes(df)));
  const auto k = hn::And(i, hn::Sub(n, hn::Set(di, 1)));
  const auto a = hn::TableLookupLanes(w0, hn::IndicesFromVec(df, k));
  const auto b = hn::TableLookupLanes(w1, hn::IndicesFromVec(df, k));
  return hn::IfThenElse(hn::RebindMask(df, hn::Lt(i, n)), a, b);
#endif
}

// pullNearest bin by bin.
template <bool kCount>
void pullByBins(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, float* bins,
                std::int32_t* counts)
{
  for (int i = 0; i < n; ++i)
  {
    const float v = nearestOf(range, lo[i], hi[i], kCount ? counts + i : nullptr);
    bins[i] = v < bins[i] ? v : bins[i];
  }
}

#if HWY_TARGET != HWY_SCALAR && HWY_TARGET != HWY_EMU128  // not the scalar target (either kind)
// pullNearest N bins at a time where each holds one or two pixels (nearly all: a bin is about a pixel wide; else those
// N bin by bin): their first and last pixels' ranges gathered, then nearestOf's two steps per lane.
// On AVX2 and AVX-512 the gathers cost more than pullChunks' lookups (frames 15-25 % slower).
template <bool kCount>
void pullPairs(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, float* bins,
               std::int32_t* counts)
{
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const int N = static_cast<int>(hn::Lanes(df));
  const auto inf = hn::Set(df, std::numeric_limits<float>::infinity());
  int j = 0;
  for (; j + N <= n; j += N)
  {
    const auto l = hn::LoadU(di, lo + j), h = hn::LoadU(di, hi + j);
    if (!hn::AllFalse(di, hn::Or(hn::Lt(h, l), hn::Gt(hn::Sub(h, l), hn::Set(di, 1)))))
    {
      pullByBins<kCount>(range, lo + j, hi + j, N, bins + j, kCount ? counts + j : nullptr);
      continue;
    }
    const auto xl = hn::GatherIndex(df, range, l), xh = hn::GatherIndex(df, range, h);
    hn::StoreU(nearer(nearer(xh, nearer(xl, inf)), hn::LoadU(df, bins + j)), df, bins + j);
    if constexpr (kCount)  // NaN and +Inf are not finite; a bin of one pixel counts it once
    {
      const auto fl = hn::RebindMask(di, hn::Lt(xl, inf));
      const auto fh = hn::And(hn::Gt(h, l), hn::RebindMask(di, hn::Lt(xh, inf)));  // two pixels, the last finite
      const auto c = hn::Sub(hn::LoadU(di, counts + j), hn::VecFromMask(di, fl));
      hn::StoreU(hn::Sub(c, hn::VecFromMask(di, fh)), di, counts + j);
    }
  }
  pullByBins<kCount>(range, lo + j, hi + j, n - j, bins + j, kCount ? counts + j : nullptr);
}
#endif

// pullNearest, N bins at a time (N float lanes): their pixels lie within 2N columns (a bin holds about one pixel),
// so two vector loads and a two-table lookup per pixel rank fetch them; chunks whose pixels spread wider take the
// scalar nearestOf. The last chunk overlaps the one before: min is idempotent, and its counts take only the new
// lanes. Rows of fewer than N bins take nearestOf bin by bin. Targets of fewer than 8 float lanes (SSE4, NEON) take
// pullPairs, the scalar target nearestOf bin by bin: with 4 lanes a chunk's fixed cost outweighs its lanes (SSE4:
// frames 8-12 % faster with the plain loop, 5-11 % faster again with pullPairs).
template <bool kCount>
void pullChunks(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, float* bins,
                std::int32_t* counts)
{
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const int N = static_cast<int>(hn::Lanes(df));
  const auto one = hn::Set(di, 1);
  const auto inf = hn::Set(df, std::numeric_limits<float>::infinity());
  const auto chunk = [&](int j, int fresh) {  // bins j .. j + N - 1; the first N - fresh are done already
    const auto l = hn::LoadU(di, lo + j), h = hn::LoadU(di, hi + j);
    const auto cnt = hn::Sub(hn::Add(h, one), l);  // pixels per bin
    const auto some = hn::Gt(cnt, hn::Zero(di));
    if (hn::AllFalse(di, some))
      return;
    // lo and hi grow (or fall) with the bin: the window is set by the chunk's end bins, and checked.
    const int base = std::min(lo[j], lo[j + N - 1]), top = std::max(hi[j], hi[j + N - 1]);
    const auto out = hn::And(some, hn::Or(hn::Lt(l, hn::Set(di, base)), hn::Gt(h, hn::Set(di, top))));
    if (top - base >= 2 * N || !hn::AllFalse(di, out))
    {
      const int k = j + N - fresh;
      pullByBins<kCount>(range, lo + k, hi + k, fresh, bins + k, kCount ? counts + k : nullptr);
      pullByBins<false>(range, lo + j, hi + j, N - fresh, bins + j, nullptr);  // their min again, not their counts
      return;
    }
    const auto w0 = hn::LoadU(df, range + base), w1 = hn::LoadU(df, range + base + N);
    auto idx = hn::Sub(l, hn::Set(di, base));
    auto v = inf;
    auto finite = hn::Zero(di);
    const auto rank = [&](auto m) HWY_ATTR {  // the pixels of rank c (idx) of the bins in m
      const auto x = lookup2(df, w0, w1, idx);
      if constexpr (kCount)  // NaN and +Inf are not finite
        finite = hn::Sub(finite, hn::VecFromMask(di, hn::RebindMask(di, hn::And(m, hn::Lt(x, inf)))));
      v = hn::IfThenElse(m, nearer(x, v), v);
      idx = hn::Add(idx, one);
    };
    // The first two pixel ranks whatever the counts (most bins hold one or two): the loop's exit is then all but
    // always at its start.
    rank(hn::RebindMask(df, some));
    rank(hn::RebindMask(df, hn::Gt(cnt, one)));
    for (int c = 2;; ++c)
    {
      const auto m = hn::RebindMask(df, hn::Gt(cnt, hn::Set(di, c)));
      if (hn::AllFalse(df, m))
        break;
      rank(m);
    }
    hn::StoreU(nearer(v, hn::LoadU(df, bins + j)), df, bins + j);
    if constexpr (kCount)
    {
      const auto fresh_lanes = hn::Not(hn::FirstN(di, static_cast<std::size_t>(N - fresh)));
      const auto add = hn::IfThenElseZero(fresh_lanes, finite);
      hn::StoreU(hn::Add(hn::LoadU(di, counts + j), add), di, counts + j);
    }
  };
#if HWY_TARGET != HWY_SCALAR && HWY_TARGET != HWY_EMU128  // not the scalar target (either kind)
  if (N < 8)
    return pullPairs<kCount>(range, lo, hi, n, bins, counts);
#endif
  if (n < N || N < 8)
    return pullByBins<kCount>(range, lo, hi, n, bins, counts);
  int j = 0;
  for (; j + N <= n; j += N)
    chunk(j, N);
  if (j < n)
    chunk(n - N, n - j);
}

void pullNearest(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, float* bins,
                 std::int32_t* counts)
{
  if (counts)
    pullChunks<true>(range, lo, hi, n, bins, counts);
  else
    pullChunks<false>(range, lo, hi, n, bins, nullptr);
}

// The column projection's: each column's bin position and range factor.
void columnLoop(const float* __restrict cb, const float* __restrict k, int u0, int u1, float beams,
                const float* __restrict z, float* __restrict fb, std::int32_t* __restrict key,
                float* __restrict range)
{
  for (int u = u0; u <= u1; ++u)
  {
    fb[u] = cb[u];
    key[u] = binKey(cb[u], beams);
    range[u] = z[u] * k[u];
  }
}
}  // namespace

const ScanKernels kScanKernels = {
    edgeBinLoop,
    spanLoop,
    rangeLoop,
    columnLoop,
    {{pixelLoop<false, false>, pixelLoop<false, true>}, {pixelLoop<true, false>, pixelLoop<true, true>}},
    pullNearest,
    {{keptRangeLoop<std::uint8_t>, keptRangeLoopLevel<std::uint8_t>},
     {keptRangeLoop<std::uint16_t>, keptRangeLoopLevel<std::uint16_t>},
     {keptRangeLoop<float>, keptRangeLoopLevel<float>}},
};
const ScanKernels* scanKernelTable() { return &kScanKernels; }
}  // namespace HWY_NAMESPACE
}  // namespace detail
}  // namespace kinect_pipeline
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kinect_pipeline
{
namespace detail
{
HWY_EXPORT(scanKernelTable);
const ScanKernels& scanKernels() { return *HWY_DYNAMIC_DISPATCH(scanKernelTable)(); }
}  // namespace detail

namespace
{
// atan2 within kCoarseAtanError rad (max 6.1e-4 on [0, 1] for the polynomial: a least-max-error fit of degree 5),
// for spanPlan's bounds: three terms fewer on the row's chain of dependent operations than fastAtan2.
constexpr double kCoarseAtanError = 1e-3;
inline float coarseAtan2(float y, float x)
{
  return atan2ByOctant(y, x, [](float a) {
    const float s = a * a;
    float r = 0.07934285f;
    r = r * s - 0.28869395f;
    r = r * s + 0.99535861f;
    return r * a;
  });
}
}  // namespace

void ScanProjector::configure(const Camera& camera, const Config& config)
{
  projection_ = config.projection;
  width_ = camera.width;
  height_ = camera.height;
  xn_.resize(width_);
  xe_.resize(width_ + 1);
  yn_.resize(height_);
  xn2_.resize(width_);
  for (int u = 0; u < width_; ++u)
  {
    xn_[u] = static_cast<float>((u - camera.cx) / camera.fx);
    xn2_[u] = xn_[u] * xn_[u];
  }
  for (int e = 0; e <= width_; ++e)
    xe_[e] = static_cast<float>((e - 0.5 - camera.cx) / camera.fx);
  for (int r = 0; r < height_; ++r)
    yn_[r] = static_cast<float>((r - camera.cy) / camera.fy);

  // Beam angle of each column edge in the column model: -theta_x (counter-clockwise from forward).
  const bool thesis_columns = projection_ == Projection::kColumn && config.geometry == Geometry::kThesis;
  const double hfov = camera.hfov();
  std::vector<double> edge_angle(width_ + 1);
  for (int e = 0; e <= width_; ++e)
    edge_angle[e] = thesis_columns ? -((e - 0.5) - 0.5 * width_) / width_ * hfov
                                   : -std::atan((e - 0.5 - camera.cx) / camera.fx);

  double lo = edge_angle[width_], hi = edge_angle[0];
  if (config.scan_fov > 0.0)
  {
    lo = -0.5 * config.scan_fov;
    hi = 0.5 * config.scan_fov;
  }
  beams_ = config.scan_beams > 0 ? config.scan_beams : width_;
  const double inc = (hi - lo) / beams_;
  inc_ = static_cast<float>(inc);
  lo_ = static_cast<float>(lo);
  angle_min_ = static_cast<float>(lo + 0.5 * inc);
  angle_max_ = static_cast<float>(hi - 0.5 * inc);

  col_factor_.resize(width_);
  for (int side = 0; side < 2; ++side)  // upside down, a column's bearing is the upright one's mirrored
  {
    const double mirror = side == 0 ? 1.0 : -1.0;
    col_edge_bins_[side].resize(width_ + 1);
    for (int e = 0; e <= width_; ++e)
      col_edge_bins_[side][e] = static_cast<float>((mirror * edge_angle[e] - lo) / inc);
    col_centre_bins_[side].resize(width_);
    for (int u = 0; u < width_; ++u)
    {
      const double theta_x =
          thesis_columns ? (u - 0.5 * width_) / width_ * hfov : std::atan((u - camera.cx) / camera.fx);
      col_factor_[u] = static_cast<float>(1.0 / std::cos(theta_x));
      col_centre_bins_[side][u] = static_cast<float>((-mirror * theta_x - lo) / inc);
    }
  }
  bx_.assign(height_, 1.0f);
  by_.assign(height_, 0.0f);
  cx_ = static_cast<float>(camera.cx);
  fx_ = static_cast<float>(camera.fx);
  border_s_.resize(beams_ + 1);
  border_c_.resize(beams_ + 1);
  border_den_.resize(beams_ + 1);
  border_p_.resize(beams_ + 1);
  border_q_.resize(beams_ + 1);
  for (int k = 0; k <= beams_; ++k)
  {
    border_s_[k] = static_cast<float>(std::sin(lo + k * inc));
    border_c_[k] = static_cast<float>(std::cos(lo + k * inc));
  }
  inv_fx_ = static_cast<float>(1.0 / camera.fx);
  coarse_margin_ = 1 + static_cast<int>(std::ceil(kCoarseAtanError / inc));
  setPose(0.0, 0.0);
}

void ScanProjector::setPose(double pitch, double roll)
{
  if (projection_ == Projection::kColumn)
  {
    col_side_ = std::cos(roll) < 0.0 ? 1 : 0;  // the column model leaves pitch and roll out but for this
    return;
  }
  // The ray (xn, yn, 1) in the level frame: x = ax xn + bx[r], y = ay xn + by[r].
  const std::array<double, 9> m = levelFromOptical(pitch, roll);
  ax_ = static_cast<float>(m[0]);
  ay_ = static_cast<float>(m[3]);
  for (int r = 0; r < height_; ++r)
  {
    bx_[r] = static_cast<float>(m[2] + m[1] * yn_[r]);
    by_[r] = static_cast<float>(m[4] * yn_[r]);
  }
  // Each border's crossing terms (see crossing()): the denominator depends on the pose, not on the row.
  const double ax = ax_, ay = ay_, fx = fx_;
  for (int k = 0; k <= beams_; ++k)
  {
    const double s = border_s_[k], c = border_c_[k];
    const double den = ay * c - ax * s;
    border_den_[k] = static_cast<float>(den);
    border_p_[k] = static_cast<float>(fx * s / den);
    border_q_[k] = static_cast<float>(fx * c / den);
  }
}

const float* ScanProjector::rowEdgeBins(int r, float* buffer) const
{
  if (projection_ == Projection::kColumn)
    return col_edge_bins_[col_side_].data();
  edgeBins(r, 0, width_, buffer);
  return buffer;
}

void ScanProjector::edgeBins(int r, int e0, int e1, float* out) const
{
  detail::scanKernels().edge_bins(xe_.data(), e0, e1, ax_, ay_, bx_[r], by_[r], lo_, 1.0f / inc_, out);
}

void ScanProjector::spanBins(int r, int u0, int u1, const float* depth, float* fb, std::int32_t* key,
                             float* range) const
{
  const float beams = static_cast<float>(beams_);
  if (projection_ == Projection::kColumn)
    detail::scanKernels().columns(col_centre_bins_[col_side_].data(), col_factor_.data(), u0, u1, beams, depth, fb,
                                  key, range);
  else
    detail::scanKernels().span_bins(xn_.data(), u0, u1, ax_, ay_, bx_[r], by_[r], lo_, 1.0f / inc_, beams, depth,
                                    fb, key, range);
}

void ScanProjector::spanRanges(int r, int u0, int u1, const float* depth, float* range) const
{
  detail::scanKernels().ranges(xn_.data(), u0, u1, ax_, ay_, bx_[r], by_[r], depth, range);
}

template <typename T>
void ScanProjector::spanKeptSquaredRanges(int r, int u0, int u1, const T* row, float scale, float* range) const
{
  const detail::KeptRangeKernels<T>& k = detail::scanKernels().kept.of<T>();
  if (ax_ == 0.0f && ay_ == -1.0f && by_[r] == 0.0f)
    k.level(xn2_.data(), u0, u1, bx_[r], row, scale, range);
  else
    k.any(xn_.data(), u0, u1, ax_, ay_, bx_[r], by_[r], row, scale, range);
}
template void ScanProjector::spanKeptSquaredRanges<std::uint8_t>(int, int, int, const std::uint8_t*, float, float*) const;
template void ScanProjector::spanKeptSquaredRanges<std::uint16_t>(int, int, int, const std::uint16_t*, float, float*) const;
template void ScanProjector::spanKeptSquaredRanges<float>(int, int, int, const float*, float, float*) const;

int ScanProjector::spanPlan(int r, int a, int b, SpanPlan& plan) const
{
  if (projection_ != Projection::kHorizontal)
    return -1;
  const float ax = ax_, ay = ay_, bx = bx_[r], by = by_[r];
  // The row's line (X, Y) = (ax, ay) xn + (bx, by) must pass clear of the point under the sensor: by its distance
  // from it (at least |bx ay - by ax|, as |(ax, ay)| <= 1) in pixels, D, a bin without a centre takes the centre
  // nearest to the middle of its borders' crossings in columns instead of in bearings, at most 1 / (4 D^2 inc)
  // bins off (the bearing's curvature over a pixel): a twentieth of a bin at most (D >= 46 pixels for 512 beams
  // over 70.6 degrees: a Kinect v2's rows are all farther up to a pitch of 0.94 rad, 100 pixels or more at 0.8).
  const float cross = std::fabs(bx * ay - by * ax), far = cross * fx_;
  if (!(cross > 1e-4f) || !(far * far * inc_ >= 5.0f))
    return -1;
  // A span whose bearings pass the direction straight behind the sensor (Y = 0 with X < 0: only rows that look
  // behind it, looking steeply down) runs from one end of the bin positions to the other: its bins are not the one
  // run k0..k1 between its ends' bins.
  const float x0 = (static_cast<float>(a - 1) - cx_) * inv_fx_, x1 = (static_cast<float>(b + 1) - cx_) * inv_fx_;
  if (ay != 0.0f)
  {
    const float behind = -by / ay;  // xn where Y = 0
    if (behind >= x0 && behind <= x1 && ax * behind + bx < 0.0f)
      return -1;
  }
  // Bins of the centres either side of the span (the pixels a - 1 and b + 1, seen as +Inf), found with a coarse
  // atan, and coarse_margin_ more each side: one for the rounding at a border, the rest for the atan's error.
  // More bins than needed only add bins without a pixel of the span.
  const float inv = 1.0f / inc_, beams = static_cast<float>(beams_);
  float f[2];
  for (int i = 0; i < 2; ++i)
  {
    const float xn = i == 0 ? x0 : x1;
    f[i] = (coarseAtan2(ay * xn + by, ax * xn + bx) - lo_) * inv;
  }
  const std::int32_t k0 = std::max(0, binKey(std::min(f[0], f[1]), beams) - coarse_margin_);
  const std::int32_t k1 = std::min(beams_ - 1, binKey(std::max(f[0], f[1]), beams) + coarse_margin_);
  if (k0 > k1)
    return 0;
  const int n = k1 - k0 + 1;
  const float* p = border_p_.data() + k0;
  const float* q = border_q_.data() + k0;
  const float* den = border_den_.data() + k0;
  const float* s = border_s_.data() + k0;
  const float* c = border_c_.data() + k0;
  // The crossings hold where each bearing crosses the line ahead (not its opposite) at a finite column: the
  // denominator keeps its sign between the ends (it is a sinusoid of the bearing, with zeros half a turn apart)
  // and the crossing lies in the bearing's direction.
  float g[2];
  for (int e = 0; e < 2; ++e)
  {
    const int i = e == 0 ? 0 : n;
    g[e] = detail::crossing<true>(p[i], q[i], bx, by, cx_);
    const float xn = (g[e] - cx_) * inv_fx_;
    if (!(std::fabs(den[i]) > 1e-6f) || !std::isfinite(g[e]) ||
        !((ax * xn + bx) * c[i] + (ay * xn + by) * s[i] > 0.0f))
      return -1;
  }
  if ((den[0] > 0.0f) != (den[n] > 0.0f))
    return -1;
  plan = SpanPlan{k0, n, g[1] > g[0], p, q, bx, by, cx_, a, b};
  return n;
}

int ScanProjector::spanPixels(int r, int a, int b, std::int32_t* lo, std::int32_t* hi, int& first) const
{
  SpanPlan plan;
  const int n = spanPlan(r, a, b, plan);
  if (n > 0)
  {
    planPixels(plan, lo, hi);
    first = plan.first;
  }
  return n;
}

void ScanProjector::planPixels(const SpanPlan& s, std::int32_t* lo, std::int32_t* hi)
{
  detail::scanKernels().pixels[s.up][s.by != 0.0f](s.p, s.q, s.n, s.bx, s.by, s.cx, s.a, s.b, lo, hi);
}

void detail::pullNearest(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, float* bins,
                         std::int32_t* counts)
{
  scanKernels().pull(range, lo, hi, n, bins, counts);
}

void ScanProjector::rowCoverage(int r, float& lo, float& hi) const
{
  if (projection_ == Projection::kColumn)
  {
    const std::vector<float>& edges = col_edge_bins_[col_side_];
    lo = std::min({lo, edges.front(), edges.back()});
    hi = std::max({hi, edges.front(), edges.back()});
    return;
  }
  const float inv = 1.0f / inc_;
  for (const float x : {xe_.front(), xe_.back()})
  {
    const float f = rayBin(x, ax_, ay_, bx_[r], by_[r], lo_, inv);
    lo = std::min(lo, f);
    hi = std::max(hi, f);
  }
}

void ScanProjector::coverage(float& lo, float& hi) const
{
  lo = std::numeric_limits<float>::infinity();
  hi = -lo;
  // The column projection's edges do not depend on the row.
  for (int r = 0; r < (projection_ == Projection::kColumn ? 1 : height_); ++r)
    rowCoverage(r, lo, hi);
}

}  // namespace kinect_pipeline
#endif  // HWY_ONCE
