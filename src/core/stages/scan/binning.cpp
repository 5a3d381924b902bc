// The scan binning of a frame's rows (stages/scan/binning.h) on ScanProjector's geometry (stages/scan/scan.cpp).
// Design notes: docs/core_design.md ("The scan").
#include "stages/scan/binning.h"

#include <array>
#include <cmath>
#include <cstring>
#include <type_traits>

#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/model/threshold_curve.h"
#include "kinect_pipeline/types.h"

namespace kinect_pipeline
{
namespace detail
{
void BinScratch::resize(std::size_t w, std::size_t beams)
{
  z.resize(w);
  range.resize(w + 32);  // the pull's vector loads read up to 31 past a span's last pixel
  lo.resize(beams);
  hi.resize(beams);
  colmin.resize(w);
  edges.resize(w + 1);
  bins.resize(beams + 2);  // from beam -1 to beams: what lies outside the scan goes to the ends
  key.resize(w);
  gaps.resize(w + 8);
  cliff_bins.resize(beams + 2);
  cliff_count.resize(beams + 2);
  band_sum.resize(beams + 2);
  band_n.resize(beams + 2);
}

namespace
{
// z[u] = depth of the kept pixel u of the cleaned row, +Inf for removed ones, for u in [u0, u1].
template <typename T>
void keptDepth(const T* __restrict dst, int u0, int u1, float scale, float* __restrict z)
{
  for (int u = u0; u <= u1; ++u)
    z[u] = keptMetres(dst[u], scale);
}

// z[u] = measured (raw) depth of the pixel u labelled kept, +Inf for the others and for no return, u in [u0, u1].
template <typename T>
void keptRawDepth(const T* __restrict in, const std::uint8_t* __restrict lab, int u0, int u1, float scale,
                  float* __restrict z)
{
  using Tr = DepthTraits<T>;
  for (int u = u0; u <= u1; ++u)
  {
    const T v = Tr::map(in[u]);
    z[u] = (lab[u] == kKept && !Tr::isNoReturn(v)) ? static_cast<float>(v) * scale : kInf;
  }
}

// range[u] = range[u]^2, u in [u0, u1].
void squareSpan(float* __restrict range, int u0, int u1)
{
  for (int u = u0; u <= u1; ++u)
    range[u] *= range[u];
}

void minInto(const float* __restrict z, int u0, int u1, float* __restrict m)
{
  for (int u = u0; u <= u1; ++u)
    m[u] = z[u] < m[u] ? z[u] : m[u];
}

// Whether lab[u..u+63] holds the label l (a fixed-length reduction: whole vectors).
__attribute__((always_inline)) inline bool blockHas(const std::uint8_t* __restrict lab, int u, std::uint8_t l)
{
  std::uint8_t any = 0;
  for (int k = 0; k < 64; ++k)
    any |= lab[u + k] == l;
  return any != 0;
}

#if defined(__BYTE_ORDER__) && __BYTE_ORDER__ != __ORDER_LITTLE_ENDIAN__
#error "labelBits and the flag scans read 8 bytes as a little-endian word"
#endif
// The high bit of each byte of the 8 labels at p that equals l (exact for every byte, not only the lowest:
// the zero-byte test of x = labels ^ l without a borrow from byte to byte). Byte i is label p[i] (little endian).
inline std::uint64_t labelBits(const std::uint8_t* p, std::uint8_t l)
{
  std::uint64_t x;
  std::memcpy(&x, p, 8);
  x ^= 0x0101010101010101ull * l;
  constexpr std::uint64_t low7 = 0x7F7F7F7F7F7F7F7Full;
  return ~(((x & low7) + low7) | x | low7);
}

// flag[u] = whether the centres of pixels u and u + 1 lie more than a bin apart, u in [a, b); 0 from b to b + 7.
void gapFlags(const std::int32_t* __restrict key, int a, int b, std::uint8_t* __restrict flag)
{
  for (int u = a; u < b; ++u)
    flag[u] = static_cast<unsigned>(key[u + 1] - key[u] + 1) > 2u;
  std::memset(flag + b, 0, 8);
}

// A gap of whole bins between the centres of pixels u and u + 1: split it at the middle (pixels wider than beams).
template <typename Acc>
inline void binGap(int u, const float* fc, const float* range, int beams, float half_turn_bins, const Acc& acc)
{
  const float r = range[u], r1 = range[u + 1];
  const float f0 = fc[u], f1 = fc[u + 1];
  if ((!(r < kInf) && !(r1 < kInf)) || std::fabs(f1 - f0) > half_turn_bins)
    return;
  const float lo = f0 < f1 ? f0 : f1, hi = f0 < f1 ? f1 : f0;
  const int k0 = std::max(0, static_cast<int>(std::floor(lo)) + 1);
  const int k1 = std::min(beams - 1, static_cast<int>(std::floor(hi)) - 1);
  const float mid = 0.5f * (lo + hi);
  const float r_lo = f0 < f1 ? r : r1, r_hi = f0 < f1 ? r1 : r;
  for (int k = k0; k <= k1; ++k)
    acc(k, (k + 0.5f) < mid ? r_lo : r_hi);
}

/**
 * Bins one row's pixels by the bearing of their centres (fc[u]: fractional bin position of pixel u's centre, key[u]
 * its bin, ScanProjector::spanBins), min per bin: a bin holds exactly the pixels whose centres fall in it. Where
 * neighbouring centres are more than one bin apart, the bins between them go to the nearer centre (in bearing), so
 * that the binning leaves no bin empty that a surface covers. Pixels whose neighbour lies half a turn away
 * (straddling the direction behind) are not used to fill.
 */
template <typename Acc>
void binByCentres(const float* fc, const float* range, int a, int b, int beams, float half_turn_bins,
                  const std::int32_t* key, std::uint8_t* flag, const Acc& acc)
{
  gapFlags(key, a, b, flag);
  for (int u = a; u <= b; ++u)
    acc(key[u], range[u]);  // bins[-1] and bins[beams] take what lies outside the scan
  // The flagged pairs come irregularly: 8 flags at a time, then their set bytes.
  for (int u0 = a; u0 < b; u0 += 8)
  {
    std::uint64_t x;
    std::memcpy(&x, flag + u0, 8);
    for (; x != 0; x &= x - 1)
      binGap(u0 + __builtin_ctzll(x) / 8, fc, range, beams, half_turn_bins, acc);
  }
}

// The pixels lo[j]..hi[j] into bin first + j, for j < n (ScanProjector::planPixels): the same bins as binByCentres
// fills from the centres' side.
template <typename Acc>
void pullBins(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, int first, const Acc& acc)
{
  for (int j = 0; j < n; ++j)
    for (int u = lo[j]; u <= hi[j]; ++u)
      acc(first + j, range[u]);
}
}  // namespace

template <typename T>
void belowFloorDepth(const T* __restrict src, const std::uint8_t* __restrict lab, int u0, int u1,
                     float scale, const float* __restrict col, float row, const CliffRule& rule,
                     float* __restrict z)
{
  for (int u = u0; u <= u1; ++u)
  {
    const float d = static_cast<float>(src[u]) * scale;
    z[u] = lab[u] == kBelowFloor && rule.evidence(d, col[u] + row) ? d : kInf;
  }
}
template void belowFloorDepth<std::uint8_t>(const std::uint8_t*, const std::uint8_t*, int, int, float, const float*,
                                            float, const CliffRule&, float*);
template void belowFloorDepth<std::uint16_t>(const std::uint16_t*, const std::uint8_t*, int, int, float,
                                             const float*, float, const CliffRule&, float*);
template void belowFloorDepth<float>(const float*, const std::uint8_t*, int, int, float, const float*, float,
                                     const CliffRule&, float*);

// 64 labels at a time, then 8 (labelBits), then one.
int firstLabelled(const std::uint8_t* __restrict lab, int w, std::uint8_t l)
{
  int u = 0;
  for (; u + 64 <= w; u += 64)
    if (blockHas(lab, u, l))
      break;
  for (; u + 8 <= w; u += 8)
    if (const std::uint64_t m = labelBits(lab + u, l))
      return u + __builtin_ctzll(m) / 8;
  while (lab[u] != l)
    ++u;
  return u;
}

int lastLabelled(const std::uint8_t* __restrict lab, int w, std::uint8_t l)
{
  int u = w;
  for (; u >= 64; u -= 64)
    if (blockHas(lab, u - 64, l))
      break;
  for (; u >= 8; u -= 8)
    if (const std::uint64_t m = labelBits(lab + u - 8, l))
      return u - 8 + (63 - __builtin_clzll(m)) / 8;
  do
    --u;
  while (lab[u] != l);
  return u;
}

template <typename Acc>
void RowBinner::binCentres(int r, int u0, int u1, const float* z, BinScratch& s, bool squared, const Acc& acc) const
{
  p_.spanBins(r, u0, u1, z, s.edges.data(), s.key.data(), s.range.data());
  if (squared)
    squareSpan(s.range.data(), u0, u1);
  binByCentres(s.edges.data(), s.range.data(), u0, u1, p_.beams(), 3.14159265f / p_.angleIncrement(), s.key.data(),
               s.gaps.data(), acc);
}

template <typename Acc, typename Src>
void RowBinner::bin(int r, int a, int b, int n, const SpanPlan& plan, BinScratch& s, const Src& src,
                    const Acc& acc) const
{
  constexpr bool kCleaned = !std::is_same_v<Src, SpanDepths>;  // KeptDepths
  if (n == 0)
    return;
  float* range = s.range.data();
  if (n > 0)
  {
    std::int32_t *lo = s.lo.data(), *hi = s.hi.data();
    ScanProjector::planPixels(plan, lo, hi);
    if constexpr (kCleaned)
      p_.spanKeptSquaredRanges(r, a, b, src.row, src.scale, range);
    else
      p_.spanRanges(r, a, b, s.z.data(), range);
    if constexpr (std::is_same_v<Acc, MinInto>)
    {
      if (vector_)
        return pullNearest(range, lo, hi, n, acc.bins + plan.first);
    }
    else if constexpr (std::is_same_v<Acc, MinCountInto>)
    {
      if (vector_)
        return pullNearest(range, lo, hi, n, acc.bins + plan.first, acc.counts + plan.first);
    }
    pullBins(range, lo, hi, n, plan.first, acc);
    return;
  }
  float* z = s.z.data();
  if constexpr (kCleaned)
    keptDepth(src.row, a, b, src.scale, z);
  const int a1 = std::max(0, a - 1), b1 = std::min(width_ - 1, b + 1);
  for (int u = a1; u < a; ++u)
    z[u] = kInf;
  for (int u = b + 1; u <= b1; ++u)
    z[u] = kInf;
  binCentres(r, a1, b1, z, s, kCleaned, acc);
}
template void RowBinner::bin<MinCountInto, SpanDepths>(int, int, int, int, const SpanPlan&, BinScratch&,
                                                       const SpanDepths&, const MinCountInto&) const;

template <typename T>
void HorizontalBinning<T>::begin(BinScratch& s, int h) const
{
  // ScanProjector::rowCoverage, split over the threads.
  s.cov_lo = kInf;
  s.cov_hi = -kInf;
#pragma omp for schedule(static) nowait
  for (int r = 0; r < h; ++r)
    binner_.projector().rowCoverage(r, s.cov_lo, s.cov_hi);
}

template <typename T>
void HorizontalBinning<T>::chunk(int r0, int r1, BinScratch& s) const
{
  std::array<SpanPlan, kRowChunk> plans;
  std::array<int, kRowChunk> n{};
  for (int r = r0; r < r1; ++r)
    if (spans_[2 * r] <= spans_[2 * r + 1])
      n[r - r0] = binner_.plan(r, spans_[2 * r], spans_[2 * r + 1], plans[r - r0]);
  const MinInto acc{s.bins.data() + 1};
  for (int r = r0; r < r1; ++r)
    if (spans_[2 * r] <= spans_[2 * r + 1])
      binner_.bin(r, spans_[2 * r], spans_[2 * r + 1], n[r - r0], plans[r - r0], s,
                  KeptDepths<T>{cleaned_.ptr<T>(r), scale_}, acc);
}

template <typename T>
void HorizontalBinning<T>::coverage(const std::vector<const BinScratch*>& team, float& lo, float& hi) const
{
  lo = kInf;
  hi = -kInf;
  for (const BinScratch* s : team)
  {
    lo = std::min(lo, s->cov_lo);
    hi = std::max(hi, s->cov_hi);
  }
}

template <typename T>
void ColumnBinning<T>::begin(BinScratch& s, int) const
{
  std::fill(s.colmin.begin(), s.colmin.end(), kInf);
}

template <typename T>
void ColumnBinning<T>::keptSpan(int, int a, int b, const T* dst, BinScratch& s) const
{
  keptDepth<T>(dst, a, b, scale_, s.z.data());
  minInto(s.z.data(), a, b, s.colmin.data());
}

template <typename T>
void ColumnBinning<T>::end(BinScratch& s) const
{
  const int w = static_cast<int>(s.colmin.size());
  binner_.binCentres(0, 0, w - 1, s.colmin.data(), s, false, MinInto{s.bins.data() + 1});
}

template <typename T>
void ColumnBinning<T>::coverage(const std::vector<const BinScratch*>&, float& lo, float& hi) const
{
  binner_.projector().coverage(lo, hi);
}

template <typename T>
void surfaceMeans(const RowBinner& binner, const cv::Mat& depth, const cv::Mat& labels, const std::int32_t* spans,
                  const Config& config, int threads, std::vector<BinScratch*>& scratch, std::vector<float>& limit,
                  std::vector<float>& ranges)
{
  const int h = depth.rows, beams = binner.projector().beams();
  limit.assign(beams + 2, -1.0f);  // padding slots: nothing is ever within
  for (int k = 0; k < beams; ++k)
  {
    const float m = ranges[k];
    if (m < kInf)
      limit[k + 1] = static_cast<float>(m + config.surface_band * evaluateCurve(config.threshold_curve, m));
  }
  const float scale = depthScale<T>(config.max_depth);
  int team = 1;  // threads OpenMP gave: only their scratch holds this pass's sums
#pragma omp parallel num_threads(threads)
  {
#ifdef _OPENMP
#pragma omp single nowait
    team = omp_get_num_threads();
#endif
    BinScratch& s = *scratch[threadId()];
    std::fill(s.band_sum.begin(), s.band_sum.end(), 0);
    std::fill(s.band_n.begin(), s.band_n.end(), 0);
    const BandSum acc{limit.data() + 1, s.band_sum.data() + 1, s.band_n.data() + 1};
#pragma omp for schedule(dynamic, 8)
    for (int r = 0; r < h; ++r)
    {
      const int a = spans[2 * r], b = spans[2 * r + 1];
      if (a > b)
        continue;
      keptRawDepth<T>(depth.ptr<T>(r), labels.ptr<std::uint8_t>(r), a, b, scale, s.z.data());
      binner.bin(r, a, b, s, SpanDepths{}, acc);
    }
  }
  for (int k = 0; k < beams; ++k)
  {
    std::int64_t sum = 0;
    std::int64_t n = 0;
    for (int i = 0; i < team; ++i)
    {
      sum += scratch[i]->band_sum[k + 1];
      n += scratch[i]->band_n[k + 1];
    }
    if (n > 0)  // always, where the beam has a finite nearest range: that pixel is within the band
      ranges[k] = static_cast<float>(static_cast<double>(sum) / static_cast<double>(n) * 1e-6);
  }
}

#define KP_INSTANTIATE(T)                                                                                         \
  template class HorizontalBinning<T>;                                                                           \
  template class ColumnBinning<T>;                                                                               \
  template void surfaceMeans<T>(const RowBinner&, const cv::Mat&, const cv::Mat&, const std::int32_t*,           \
                                const Config&, int, std::vector<BinScratch*>&, std::vector<float>&,              \
                                std::vector<float>&);
KP_INSTANTIATE(std::uint8_t)
KP_INSTANTIATE(std::uint16_t)
KP_INSTANTIATE(float)
#undef KP_INSTANTIATE
}  // namespace detail
}  // namespace kinect_pipeline
