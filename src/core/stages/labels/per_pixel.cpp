// The reference labeller: the plane removal rule (stages/labels/rule.h) pixel by pixel, its loops compiled once
// per SIMD target, and the rescue (stages/labels/per_pixel.h). Design notes: docs/core_design.md ("The rule",
// "Stage 2: labels"; "SIMD kernels and their references").
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "stages/labels/per_pixel.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "stages/labels/per_pixel.h"

#include <algorithm>
#include <cstdlib>
#include <cstring>
#include <type_traits>

#include "base/simd.h"

// The loops of one SIMD target.
#ifndef KP_PER_PIXEL_KERNELS
#define KP_PER_PIXEL_KERNELS
namespace kinect_pipeline
{
namespace detail
{
template <typename T>
struct PixelKernelsOf
{
  RowCounts (*classify[2][2])(const T* src, const T* in, const float* t, const float* fh, const float* col,
                              float rise_row, PlaneRule rule, int w, std::uint8_t* lab, T* dst, std::uint8_t* cand);
  void (*threshold[2])(const T* src, const ThresholdLut& lut, float scale, int w, float* t);  ///< plain, gather
};
struct PixelKernels
{
  ByDepthType<PixelKernelsOf> types;
  void (*lift_steps)(const float* col, float rise_row, float lo, float inv_step, int last, int w, std::int32_t* k);
  bool (*lift_lookup)(const float* col, float rise_row, float floor_h, const FloorLift& lift, int first, int spread,
                      int w, std::int32_t* steps, float* fh);
};
}  // namespace detail
}  // namespace kinect_pipeline
#endif

HWY_BEFORE_NAMESPACE();
namespace kinect_pipeline
{
namespace detail
{
namespace HWY_NAMESPACE
{
namespace
{
// A labelled row's counts (cand nullptr: no candidates), in blocks whose byte sums cannot wrap, of 192 pixels (whole
// vectors of every width: no scalar tail in a row of 512). The compiler vectorises the byte sums; counted in the
// labelling's loop, five 32-bit sums took its registers (16-bit rolled frames 5-9 % slower, 8-bit 9-16 %).
RowCounts countRow(const std::uint8_t* __restrict lab, const std::uint8_t* __restrict cand, int w)
{
  RowCounts c;
  for (int u0 = 0; u0 < w; u0 += 192)
  {
    const int n = std::min(192, w - u0);
    std::uint8_t inv = 0, floor = 0, ceil = 0, below = 0, flags = 0;
    for (int u = u0; u < u0 + n; ++u)
    {
      inv += lab[u] == kInvalid;
      floor += lab[u] == kFloor;
      ceil += lab[u] == kAboveCeiling;
      below += lab[u] == kBelowFloor;
    }
    if (cand)
      for (int u = u0; u < u0 + n; ++u)
        flags += cand[u];
    c.invalid += inv;
    c.floor += floor;
    c.ceiling += ceil;
    c.kept -= inv + floor + ceil + below;
    c.candidates += flags;
  }
  c.kept += w;
  return c;
}

// Branch-free, with restrict pointers, so that the compiler vectorises it. kLift: the floor offsets of a floor profile
// (liftRow()).
template <typename T, bool kRescue, bool kLift>
RowCounts classifyRow(const T* __restrict src, const T* __restrict in, const float* __restrict t,
                      const float* __restrict fh, const float* __restrict col, float rise_row,
                      PlaneRule rule, int w, std::uint8_t* __restrict lab, T* __restrict dst,
                      std::uint8_t* __restrict cand)
{
  using Tr = DepthTraits<T>;
  const T removed = Tr::removed();
  for (int u = 0; u < w; ++u)
  {
    const T v = src[u];
    float d;
    bool keep, below;
    const std::uint8_t l = rule.label(v, t[u], col[u] + rise_row, kLift ? fh[u] : rule.floor_h, d, keep, below);
    lab[u] = l;
    dst[u] = keep ? v : removed;
    if constexpr (kRescue)
    {
      // From the unmapped raw value (unknown ones are 0 or below: moved < 0; or no return): a select before the
      // conversion would stop the vectoriser.
      const T raw = in[u];
      const bool flag = (keep | below) & !Tr::isNoReturn(raw) & (rule.moved(raw, v) > PlaneRule::moveBand(t[u]));
      cand[u] = flag;
    }
  }
  return countRow(lab, kRescue ? cand : nullptr, w);
}

// The lift table's step of each pixel of a row under a floor profile (vectorised: no gather).
void liftSteps(const float* __restrict col, float rise_row, float lo, float inv_step, int last, int w,
               std::int32_t* __restrict k)
{
  const float top = static_cast<float>(last);
  for (int u = 0; u < w; ++u)
  {
    float i = (col[u] + rise_row - lo) * inv_step;  // FloorLift::step(), in a form the compiler vectorises
    i = i < top ? i : top;
    i = i > 0.0f ? i : 0.0f;
    k[u] = static_cast<std::int32_t>(i);
  }
}

// liftRow()'s offsets of a row that reads fewer lift steps than a vector has lanes (first .. first + spread): the
// steps (liftSteps, into steps), then each pixel's offset from a vector of the row's offsets (a lookup within one
// vector, no gather). @return false (nothing written) for more steps, or a row narrower than a vector.
bool liftLookup(const float* col, float rise_row, float floor_h, const FloorLift& lift, int first, int spread, int w,
                std::int32_t* __restrict steps, float* __restrict fh)
{
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::ScalableTag<float> df;
  const hn::RebindToSigned<decltype(df)> di;
  const int n = static_cast<int>(hn::Lanes(df));
  if (spread >= n || w < n)
    return false;
  liftSteps(col, rise_row, lift.lo, lift.inv_step, lift.last, w, steps);
  HWY_ALIGN float offsets[HWY_MAX_BYTES / sizeof(float)];
  for (int i = 0; i < n; ++i)
    offsets[i] = floor_h + lift.table[std::min(first + i, lift.last)];
  const auto table = hn::Load(df, offsets);
  const auto base = hn::Set(di, first);
  const auto at = [&](int u) HWY_ATTR {
    const auto k = hn::Sub(hn::LoadU(di, steps + u), base);
    hn::StoreU(hn::TableLookupLanes(table, hn::IndicesFromVec(df, k)), df, fh + u);
  };
  int u = 0;
  for (; u + n <= w; u += n)
    at(u);
  if (u < w)  // the last n pixels again (the same values where they overlap)
    at(w - n);
  return true;
}

template <typename T>
void thresholdRow(const T* __restrict src, const ThresholdLut& lut, float scale, int w, float* __restrict t)
{
  for (int u = 0; u < w; ++u)
    t[u] = thresholdOf(lut, src[u], scale);
}

// thresholdRow with 8 float lanes or more (SSE4 and NEON: the plain loop). Each vector's cells of the table (8-bit:
// the values; float: forDepth()'s cells, computed as there with its clamps as selects, NaN to the last cell), then
// their thresholds by a lookup within one vector of the table where the cells span fewer than its lanes (neighbouring
// pixels lie at nearby depths: 94 % of the 8-lane vectors of 67 real frames' 8-bit values), else by the CPU's gather.
// The window pays for 8-bit pixels (rolled frames 3-13 % faster) and for floats in 16 lanes (AVX-512: 1-9 %), not
// for floats in 8 (AVX2: 0-5 % slower on real frames) nor for 16-bit values (1 cm cells: 85 % of the vectors, frames
// 1-6 % slower): those gather from the whole table (16-bit: forMillimetres'). GCC's own vectors of the plain loop
// load each lane on its own (AVX-512: 16-bit rolled frames 5-9 % slower than not vectorising it).
template <typename T>
void thresholdGather(const T* __restrict src, const ThresholdLut& lut, float scale, int w, float* __restrict t)
{
  namespace hn = hwy::HWY_NAMESPACE;
  const hn::ScalableTag<float> df;
  const hn::Rebind<std::int32_t, decltype(df)> di;
  const hn::Rebind<T, decltype(df)> dt;
  const int n = static_cast<int>(hn::Lanes(df));
  const bool by_mm = std::is_same_v<T, std::uint16_t>;
  const float* table = by_mm ? lut.valueTable() : lut.table().data();
  const int size = by_mm ? 65536 : static_cast<int>(lut.table().size());
  const bool window = (std::is_same_v<T, std::uint8_t> || (std::is_same_v<T, float> && n >= 16)) && size >= n;
  const auto cells = [&](int i) HWY_ATTR {
    if constexpr (std::is_same_v<T, float>)
    {
      const auto top = hn::Set(df, lut.lastCell());
      auto c = hn::Mul(hn::Mul(hn::LoadU(df, src + i), hn::Set(df, scale)), hn::Set(df, ThresholdLut::kCellsPerMetre));
      c = hn::IfThenElse(hn::Lt(c, top), c, top);
      c = hn::IfThenElse(hn::Gt(c, hn::Zero(df)), c, hn::Zero(df));
      return hn::ConvertTo(di, c);
    }
    else
      return hn::BitCast(di, hn::PromoteTo(hn::Rebind<std::uint32_t, decltype(df)>(), hn::LoadU(dt, src + i)));
  };
  int u = 0;
  for (; n >= 8 && u + n <= w; u += n)
  {
    const auto k = cells(u);
    const int base = window ? std::min(hn::GetLane(hn::MinOfLanes(di, k)), size - n) : 0;
    const auto off = hn::Sub(k, hn::Set(di, base));  // >= 0
    if (window && hn::AllTrue(di, hn::Lt(off, hn::Set(di, n))))
      hn::StoreU(hn::TableLookupLanes(hn::LoadU(df, table + base), hn::IndicesFromVec(df, off)), df, t + u);
    else
      hn::StoreU(hn::GatherIndex(df, table, k), df, t + u);
  }
  thresholdRow(src + u, lut, scale, w - u, t + u);
}

template <typename T>
constexpr PixelKernelsOf<T> kernelsOf()
{
  return {{{classifyRow<T, false, false>, classifyRow<T, false, true>},
           {classifyRow<T, true, false>, classifyRow<T, true, true>}},
          {thresholdRow<T>, thresholdGather<T>}};
}
}  // namespace

const PixelKernels kPixelKernels = {{kernelsOf<std::uint8_t>(), kernelsOf<std::uint16_t>(), kernelsOf<float>()},
                                    liftSteps, liftLookup};
const PixelKernels* pixelKernelTable() { return &kPixelKernels; }
}  // namespace HWY_NAMESPACE
}  // namespace detail
}  // namespace kinect_pipeline
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kinect_pipeline
{
namespace detail
{
HWY_EXPORT(pixelKernelTable);
const PixelKernels& pixelKernels() { return *HWY_DYNAMIC_DISPATCH(pixelKernelTable)(); }

// One loop of both, or floorAt() per pixel, does not vectorise and costs four times as much.
void liftRow(const float* col, float rise_row, const PlaneRule& rule, int w, std::int32_t* steps, float* fh)
{
  pixelKernels().lift_steps(col, rise_row, rule.lift.lo, rule.lift.inv_step, rule.lift.last, w, steps);
  for (int u = 0; u < w; ++u)
    fh[u] = rule.floor_h + rule.lift.table[steps[u]];
}

bool liftRowByRuns(const float* col, float rise_row, const PlaneRule& rule, int w, float* fh)
{
  constexpr int kMaxRuns = 16;  // beyond, bisecting costs more than liftRow()'s vectorised steps and gather
  const FloorLift& lift = rule.lift;
  const auto stepAt = [&](int u) { return lift.step(col[u] + rise_row); };
  if (std::abs(stepAt(w - 1) - stepAt(0)) >= kMaxRuns)
    return false;
  for (int u = 0; u < w;)
  {
    const int s = stepAt(u);
    int end = u + 1, hi = w;  // the run's end: its first pixel of another step, in (u, w]
    while (end < hi)
    {
      const int m = (end + hi) / 2;
      if (stepAt(m) == s)
        end = m + 1;
      else
        hi = m;
    }
    std::fill(fh + u, fh + end, rule.floor_h + lift.table[s]);
    u = end;
  }
  return true;
}

bool liftRowByLookup(const float* col, float rise_row, const PlaneRule& rule, int w, std::int32_t* steps, float* fh)
{
  const int a = rule.lift.step(col[0] + rise_row), b = rule.lift.step(col[w - 1] + rise_row);
  return pixelKernels().lift_lookup(col, rise_row, rule.floor_h, rule.lift, std::min(a, b), std::abs(b - a), w, steps,
                                    fh);
}

namespace
{
// The rescue of pixel u: @return true if it relabelled the pixel.
template <typename T>
inline bool rescuePixel(int u, const T* in, const T* src, const ThresholdLut& lut, const float* col, float rise_row,
                        const PlaneRule& rule, std::uint8_t* lab, T* dst, RowCounts& c)
{
  using Tr = DepthTraits<T>;
  if (lab[u] != kKept && lab[u] != kBelowFloor)
    return false;
  const T raw = Tr::map(in[u]);
  if (raw == src[u] || Tr::isNoReturn(raw))
    return false;
  const std::uint8_t label = rule.rescued(raw, src[u], thresholdOf(lut, raw, rule.scale), col[u] + rise_row);
  if (label == kKept)
    return false;
  if (lab[u] == kKept)
    --c.kept;
  if (label == kFloor)
    ++c.floor;
  else
    ++c.ceiling;
  lab[u] = label;
  dst[u] = Tr::removed();
  return true;
}

}  // namespace

// 8 flags (0/1 bytes) at a time, then their set bytes.
template <typename T>
void rescueRow(const RuleTerms& f, int r, const std::uint8_t* cand, const T* in, const T* src, int w,
               std::uint8_t* lab, T* dst, RowCounts& c)
{
  const float rise_row = f.row[r];
  const int full = w & ~7;
  for (int u0 = 0; u0 < full; u0 += 8)
  {
    std::uint64_t x;
    std::memcpy(&x, cand + u0, 8);
    for (; x != 0; x &= x - 1)
      rescuePixel<T>(u0 + __builtin_ctzll(x) / 8, in, src, *f.lut, f.col, rise_row, f.rule, lab, dst, c);
  }
  for (int u = full; u < w; ++u)
    if (cand[u])
      rescuePixel<T>(u, in, src, *f.lut, f.col, rise_row, f.rule, lab, dst, c);
}

template <typename T>
void rowThresholds(const T* src, const ThresholdLut& lut, float scale, int w, float* t, bool gather)
{
  pixelKernels().types.of<T>().threshold[gather](src, lut, scale, w, t);
}

namespace
{
// Whether every pixel of row r has one floor offset under a floor profile, @p fh: a row of one rise, or (lift by runs)
// one whose two ends read one step of the lift, as all its pixels then do (liftRowByRuns()). The offset is the one
// liftRow() would give each pixel (floor_h plus the step's lift), so the row is labelled as without a profile.
bool oneFloorOffset(const RuleTerms& f, int r, int w, float& fh)
{
  const float rise = f.col[0] + f.row[r];
  if (!f.one_rise_per_row && !(f.lift_by_runs && f.rule.lift.step(rise) == f.rule.lift.step(f.col[w - 1] + f.row[r])))
    return false;
  fh = f.rule.floorAt(rise);
  return true;
}
}  // namespace

template <typename T>
RowCounts labelRowByPixel(const RuleTerms& f, int r, const T* src, const T* in, int w, std::uint8_t* lab, T* dst,
                          float* t, float* fh, std::int32_t* steps, std::uint8_t* cand)
{
  rowThresholds(src, *f.lut, f.rule.scale, w, t, f.vectors);
  PlaneRule rule = f.rule;
  RowCounts c;
  if (rule.lift.table && !oneFloorOffset(f, r, w, rule.floor_h))
  {
    const bool few_steps = f.lift_by_runs && ((f.vectors && liftRowByLookup(f.col, f.row[r], f.rule, w, steps, fh)) ||
                                              liftRowByRuns(f.col, f.row[r], f.rule, w, fh));
    if (!few_steps)
      liftRow(f.col, f.row[r], f.rule, w, steps, fh);
    c = in ? classifyRow<T, true, true>(src, in, t, fh, f.col, f.row[r], rule, w, lab, dst, cand)
           : classifyRow<T, false, true>(src, nullptr, t, fh, f.col, f.row[r], rule, w, lab, dst, nullptr);
  }
  else
    c = in ? classifyRow<T, true, false>(src, in, t, nullptr, f.col, f.row[r], rule, w, lab, dst, cand)
           : classifyRow<T, false, false>(src, nullptr, t, nullptr, f.col, f.row[r], rule, w, lab, dst, nullptr);
  if (c.candidates > 0)
    rescueRow<T>(f, r, cand, in, src, w, lab, dst, c);
  return c;
}

template <typename T, bool kRescue, bool kLift>
RowCounts classifyRow(const T* src, const T* in, const float* t, const float* fh, const float* col, float rise_row,
                      PlaneRule rule, int w, std::uint8_t* lab, T* dst, std::uint8_t* cand)
{
  return pixelKernels().types.of<T>().classify[kRescue][kLift](src, in, t, fh, col, rise_row, rule, w, lab, dst, cand);
}

#define KP_CLASSIFY(T, R, L)                                                                                         \
  template RowCounts classifyRow<T, R, L>(const T*, const T*, const float*, const float*, const float*, float,      \
                                          PlaneRule, int, std::uint8_t*, T*, std::uint8_t*);
#define KP_INSTANTIATE(T)                                                                                            \
  KP_CLASSIFY(T, true, false)                                                                                        \
  KP_CLASSIFY(T, false, false)                                                                                       \
  KP_CLASSIFY(T, true, true)                                                                                         \
  KP_CLASSIFY(T, false, true)                                                                                        \
  template void rescueRow<T>(const RuleTerms&, int, const std::uint8_t*, const T*, const T*, int, std::uint8_t*, T*, \
                             RowCounts&);                                                                           \
  template void rowThresholds<T>(const T*, const ThresholdLut&, float, int, float*, bool);                           \
  template RowCounts labelRowByPixel<T>(const RuleTerms&, int, const T*, const T*, int, std::uint8_t*, T*, float*,  \
                                        float*, std::int32_t*, std::uint8_t*);
KP_INSTANTIATE(std::uint8_t)
KP_INSTANTIATE(std::uint16_t)
KP_INSTANTIATE(float)
#undef KP_INSTANTIATE
#undef KP_CLASSIFY
}  // namespace detail
}  // namespace kinect_pipeline
#endif  // HWY_ONCE
