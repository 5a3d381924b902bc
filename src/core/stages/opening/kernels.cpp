// The opening's row kernels (stages/opening_kernels.h), plain loops compiled once per SIMD target, checked against
// OpenCV bit for bit. Design notes: docs/core_design.md ("Stage 1: the opening"; "SIMD kernels and their
// references").
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "stages/opening/kernels.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "kinect_pipeline/stages/opening_kernels.h"

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "kinect_pipeline/model/encoding.h"
#include "stages/opening/row_kernels.h"

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
template <bool kMin, typename T>
inline T pick(T a, T b)
{
  if constexpr (kMin)
    return b < a ? b : a;
  else
    return b > a ? b : a;
}

// Horizontal pass: the window is clamped at the image edges, which for min/max equals OpenCV's default
// border (a value that never wins).
template <typename T, bool kMin>
void horizontal(const T* tmp, int w, int rad, T* dst)
{
  if (rad == 1 && w >= 3)
  {
    dst[0] = pick<kMin>(tmp[0], tmp[1]);
    for (int u = 1; u < w - 1; ++u)
      dst[u] = pick<kMin>(pick<kMin>(tmp[u - 1], tmp[u]), tmp[u + 1]);
    dst[w - 1] = pick<kMin>(tmp[w - 2], tmp[w - 1]);
    return;
  }
  for (int u = 0; u < w; ++u)
  {
    const int a = std::max(0, u - rad), b = std::min(w - 1, u + rad);
    T m = tmp[a];
    for (int k = a + 1; k <= b; ++k)
      m = pick<kMin>(m, tmp[k]);
    dst[u] = m;
  }
}

// The order of min / max on the values after DepthTraits<T>::map, without mapping each value: an integer value
// v becomes v - m (wrapping; m the smallest known value), which puts the unknown values above every known one,
// where map puts them (at the no-return value, the largest). back() undoes it, unknown to no-return.
template <typename T, bool kMap>
struct MapOrder
{
  static T key(T v) { return v; }
  static T back(T k) { return k; }
};
template <typename T>
struct MapOrder<T, true>  // integers
{
  static constexpr T kSmallest = DepthTraits<T>::kMinValid;
  static T key(T v) { return static_cast<T>(v - kSmallest); }
  static T back(T k)
  {
    return k > static_cast<T>(DepthTraits<T>::kNoReturn - kSmallest) ? DepthTraits<T>::kNoReturn
                                                                     : static_cast<T>(k + kSmallest);
  }
};

// Floats have no cheap order key: the map itself (unknown values, NaN among them, become +Inf, above every known one).
template <>
struct MapOrder<float, true>
{
  static float key(float v) { return DepthTraits<float>::map(v); }
  static float back(float k) { return k; }
};

// The 3x3 case of rectRow / erodeMappedRow in one pass over the three source rows (a, b, c; repeated at the
// image's top and bottom), nine loads per pixel and no intermediate row: a row of vertical minima stored and
// read back at an offset of one pixel waits for the stores to reach the cache.
// The interior in blocks of a fixed 64 pixels (whole vectors, no scalar tail): the last block overlaps the one
// before it instead of leaving a remainder.
template <typename T, bool kMin, bool kMap>
void box3Row(const T* __restrict a, const T* __restrict b, const T* __restrict c, int w, T* __restrict dst)
{
  using O = MapOrder<T, kMap>;
  const auto col = [&](int u) { return pick<kMin>(pick<kMin>(O::key(a[u]), O::key(b[u])), O::key(c[u])); };
  const auto run = [&](int u0, int n)
  {
    for (int u = u0; u < u0 + n; ++u)
      dst[u] = O::back(pick<kMin>(pick<kMin>(col(u - 1), col(u)), col(u + 1)));
  };
  constexpr int kBlock = 64;
  dst[0] = O::back(pick<kMin>(col(0), col(1)));
  if (w - 2 < kBlock)
  {
    run(1, w - 2);
  }
  else
  {
    int u = 1;
    for (; u + kBlock <= w - 1; u += kBlock)
      run(u, kBlock);
    if (u < w - 1)
      run(w - 1 - kBlock, kBlock);
  }
  dst[w - 1] = O::back(pick<kMin>(col(w - 2), col(w - 1)));
}

// The 3x3 case with Highway ops: the column minima (maxima) of the three rows once per pixel, in registers, and
// their neighbours by shifting a vector by one lane across the previous or next one instead of loading six more
// rows' worth at offsets of one pixel. Min and max (floats: in pick's operand order on x86, pick's compare and
// select elsewhere, the same bits for NaN) and the order key are exact: the same bits as box3Row. The row ends
// repeat their pixel (pick(x, x) = x), as box3Row's ends leave it out.
// Highway 1.0 shifts across whole vectors only for 128-bit targets (CombineShiftRightBytes; SVE2_128's is one EXT);
// AVX2 and AVX-512 take two intrinsics each (on integer lanes: floats shift as their bits), and other targets (SVE
// of any length, one-lane scalar) box3Row.
#undef KP_BOX3_VECTORS  // this file is compiled once per target
#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX2 || HWY_TARGET == HWY_SSE4 || HWY_TARGET == HWY_NEON || \
    HWY_TARGET == HWY_SVE2_128 || HWY_TARGET == HWY_EMU128
#define KP_BOX3_VECTORS 1
template <typename T, class V>
HWY_INLINE V left1(V cur, V prev)  // [prev's last lane, cur's lanes but the last]: left neighbours
{
  constexpr int s = sizeof(T);
#if HWY_TARGET == HWY_AVX3
  return V{_mm512_alignr_epi8(cur.raw, _mm512_alignr_epi32(cur.raw, prev.raw, 12), 16 - s)};
#elif HWY_TARGET == HWY_AVX2
  return V{_mm256_alignr_epi8(cur.raw, _mm256_permute2x128_si256(prev.raw, cur.raw, 0x21), 16 - s)};
#else
  return hn::CombineShiftRightBytes<16 - s>(hn::Full128<T>(), cur, prev);
#endif
}
template <typename T, class V>
HWY_INLINE V right1(V cur, V next)  // [cur's lanes but the first, next's first lane]: right neighbours
{
  constexpr int s = sizeof(T);
#if HWY_TARGET == HWY_AVX3
  return V{_mm512_alignr_epi8(_mm512_alignr_epi32(next.raw, cur.raw, 4), cur.raw, s)};
#elif HWY_TARGET == HWY_AVX2
  return V{_mm256_alignr_epi8(_mm256_permute2x128_si256(cur.raw, next.raw, 0x21), cur.raw, s)};
#else
  return hn::CombineShiftRightBytes<s>(hn::Full128<T>(), next, cur);
#endif
}

// left1 (kLeft: other is the previous vector) or right1 (the next) of lanes of T: floats shift as their bits.
template <bool kLeft, typename T, class V>
HWY_INLINE V shift1(V cur, V other)
{
  if constexpr (std::is_floating_point_v<T>)
  {
    const hn::DFromV<V> d;
    const hn::RebindToUnsigned<decltype(d)> du;
    return hn::BitCast(d, shift1<kLeft, std::uint32_t>(hn::BitCast(du, cur), hn::BitCast(du, other)));
  }
  else if constexpr (kLeft)
    return left1<T>(cur, other);
  else
    return right1<T>(cur, other);
}

template <typename T, bool kMin, bool kMap>
void box3Vectors(const T* a, const T* b, const T* c, int w, T* dst)
{
  using O = MapOrder<T, kMap>;
  constexpr bool kFloat = std::is_floating_point_v<T>;
  const hn::ScalableTag<T> d;
  const int L = static_cast<int>(hn::Lanes(d));
  const auto pickV = [](auto x, auto y) {  // pick(x, y)
#if HWY_TARGET == HWY_AVX3 || HWY_TARGET == HWY_AVX2 || HWY_TARGET == HWY_SSE4
    // x86's min(y, x) is y < x ? y : x (max likewise), NaN included: pick itself, one instruction.
    return kMin ? hn::Min(y, x) : hn::Max(y, x);
#else
    if constexpr (kFloat)  // NEON's min and max give NaN where either is: pick's compare and select
      return kMin ? hn::IfThenElse(hn::Lt(y, x), y, x) : hn::IfThenElse(hn::Gt(y, x), y, x);
    else
      return kMin ? hn::Min(x, y) : hn::Max(x, y);
#endif
  };
  const auto key = [&](const T* p) {  // MapOrder::key
    const auto v = hn::LoadU(d, p);
    if constexpr (!kMap)
      return v;
    else if constexpr (kFloat)  // DepthTraits<float>::map
      return hn::IfThenElse(hn::And(hn::Gt(v, hn::Zero(d)), hn::Lt(v, hn::Set(d, DepthTraits<float>::kNoReturn))), v,
                            hn::Set(d, DepthTraits<float>::kNoReturn));
    else  // v - kSmallest (wrapping)
      return hn::Sub(v, hn::Set(d, MapOrder<T, true>::kSmallest));
  };
  const auto back = [&](auto k) {  // MapOrder::back: integer keys above no-return - smallest were unknown values
    if constexpr (!kMap || kFloat)
      return k;
    else
    {
      constexpr T kSmallest = MapOrder<T, true>::kSmallest, none = DepthTraits<T>::kNoReturn;
      const auto unknown = hn::Gt(k, hn::Set(d, static_cast<T>(none - kSmallest)));
      return hn::IfThenElse(unknown, hn::Set(d, none), hn::Add(k, hn::Set(d, kSmallest)));
    }
  };
  const auto column = [&](int u) { return pickV(pickV(key(a + u), key(b + u)), key(c + u)); };
  const auto splatColumn = [&](int u) {  // the column of pixel u alone, in every lane
    return hn::Set(d, pick<kMin>(pick<kMin>(O::key(a[u]), O::key(b[u])), O::key(c[u])));
  };
  const int full = w / L * L;
  auto cur = column(0);
  auto prev = splatColumn(0);
  for (int u = 0; u < full; u += L)
  {
    // The next whole vector, or (the last one) the pixel after this vector or the row's last pixel repeated.
    const auto next = u + 2 * L <= w ? column(u + L) : splatColumn(std::min(u + L, w - 1));
    hn::StoreU(back(pickV(pickV(shift1<true, T>(cur, prev), cur), shift1<false, T>(cur, next))), d, dst + u);
    prev = cur;
    cur = next;
  }
  if (full < w)  // the last L pixels once more (the same values where they overlap)
  {
    const int u = w - L;  // >= 1
    const auto x = column(u);
    hn::StoreU(back(pickV(pickV(column(u - 1), x), shift1<false, T>(x, splatColumn(w - 1)))), d, dst + u);
  }
}
#endif

// Whether box3Rows takes box3Vectors for a row of w pixels: a vector or more, on the targets that have them.
template <typename T>
bool box3InVectors(int w)
{
#if defined(KP_BOX3_VECTORS)
  return w >= static_cast<int>(hn::Lanes(hn::ScalableTag<T>()));
#else
  (void)w;
  return false;
#endif
}

// box3Row from the three rows given (w >= 3): box3Vectors for rows of a vector or more.
template <typename T, bool kMin, bool kMap>
void box3Rows(const T* a, const T* b, const T* c, int w, T* dst)
{
#if defined(KP_BOX3_VECTORS)
  if (box3InVectors<T>(w))
    return box3Vectors<T, kMin, kMap>(a, b, c, w, dst);
#endif
  box3Row<T, kMin, kMap>(a, b, c, w, dst);
}

}  // namespace

// box3Rows of row r of src and its neighbours (the row itself at the image's top and bottom).
template <typename T, bool kMin, bool kMap>
void box3(const cv::Mat& src, int r, T* dst)
{
  const T* b = src.ptr<T>(r);
  const T* a = r > 0 ? src.ptr<T>(r - 1) : b;
  const T* c = r + 1 < src.rows ? src.ptr<T>(r + 1) : b;
  box3Rows<T, kMin, kMap>(a, b, c, src.cols, dst);
}
template <typename T, bool kMin>
void rectRow(const cv::Mat& src, int r, int rad, T* tmp, T* dst)
{
  const int w = src.cols;
  if (rad == 1 && w >= 3)
    return box3<T, kMin, false>(src, r, dst);
  const int lo = std::max(0, r - rad), hi = std::min(src.rows - 1, r + rad);
  const T* first = src.ptr<T>(lo);
  std::copy(first, first + w, tmp);
  for (int j = lo + 1; j <= hi; ++j)
  {
    const T* row = src.ptr<T>(j);
    for (int u = 0; u < w; ++u)
      tmp[u] = pick<kMin>(tmp[u], row[u]);
  }
  horizontal<T, kMin>(tmp, w, rad, dst);
}

template <typename T>
void dilate3Rows(const T* a, const T* b, const T* c, int w, T* dst)
{
  if (w < 3)
  {
    // box3Row needs three columns: the general path of a one-row image of the three rows' maxima.
    T col[2];
    for (int u = 0; u < w; ++u)
      col[u] = pick<false>(pick<false>(a[u], b[u]), c[u]);
    horizontal<T, false>(col, w, 1, dst);
    return;
  }
  box3Rows<T, false, false>(a, b, c, w, dst);
}

template <typename T>
void erodeMappedRow(const cv::Mat& src, int r, int rad, T* tmp, T* dst)
{
  using Tr = DepthTraits<T>;
  const int w = src.cols;
  // Floats in vectors only: mapping each of box3Row's nine loads costs more than the separable passes' wait.
  if (rad == 1 && w >= 3 && (!std::is_floating_point_v<T> || box3InVectors<T>(w)))
    return box3<T, true, true>(src, r, dst);
  const int lo = std::max(0, r - rad), hi = std::min(src.rows - 1, r + rad);
  const T* first = src.ptr<T>(lo);
  for (int u = 0; u < w; ++u)
    tmp[u] = Tr::map(first[u]);
  for (int j = lo + 1; j <= hi; ++j)
  {
    const T* row = src.ptr<T>(j);
    for (int u = 0; u < w; ++u)
      tmp[u] = pick<true>(tmp[u], Tr::map(row[u]));
  }
  horizontal<T, true>(tmp, w, rad, dst);
}

template <typename T>
constexpr RowKernels<T> kernelsOf()
{
  return {rectRow<T, true>, rectRow<T, false>, erodeMappedRow<T>, dilate3Rows<T>};
}
const OpeningKernels kOpeningKernels = {kernelsOf<std::uint8_t>(), kernelsOf<std::uint16_t>(), kernelsOf<float>()};
const OpeningKernels* openingKernelTable() { return &kOpeningKernels; }
}  // namespace HWY_NAMESPACE
}  // namespace detail
}  // namespace kinect_pipeline
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kinect_pipeline
{
namespace detail
{
HWY_EXPORT(openingKernelTable);
const OpeningKernels& openingKernels() { return *HWY_DYNAMIC_DISPATCH(openingKernelTable)(); }

template <typename T, bool kMin>
void rectRow(const cv::Mat& src, int r, int rad, T* tmp, T* dst)
{
  const RowKernels<T>& k = openingKernels().of<T>();
  (kMin ? k.erode : k.dilate)(src, r, rad, tmp, dst);
}
template <typename T>
void erodeMappedRow(const cv::Mat& src, int r, int rad, T* tmp, T* dst)
{
  openingKernels().of<T>().erode_mapped(src, r, rad, tmp, dst);
}
template <typename T>
void dilate3Rows(const T* a, const T* b, const T* c, int w, T* dst)
{
  openingKernels().of<T>().dilate3(a, b, c, w, dst);
}

#define KP_INSTANTIATE(T)                                                 \
  template void rectRow<T, true>(const cv::Mat&, int, int, T*, T*);       \
  template void rectRow<T, false>(const cv::Mat&, int, int, T*, T*);      \
  template void erodeMappedRow<T>(const cv::Mat&, int, int, T*, T*);     \
  template void dilate3Rows<T>(const T*, const T*, const T*, int, T*);
KP_INSTANTIATE(std::uint8_t)
KP_INSTANTIATE(std::uint16_t)
KP_INSTANTIATE(float)
#undef KP_INSTANTIATE
}  // namespace detail

namespace
{
template <typename T>
void openRect(const cv::Mat& src, cv::Mat& dst, int rad, cv::Mat& scratch)
{
  scratch.create(src.size(), src.type());
  dst.create(src.size(), src.type());
  std::vector<T> tmp(src.cols);
  for (int r = 0; r < src.rows; ++r)
    detail::rectRow<T, true>(src, r, rad, tmp.data(), scratch.ptr<T>(r));
  for (int r = 0; r < src.rows; ++r)
    detail::rectRow<T, false>(scratch, r, rad, tmp.data(), dst.ptr<T>(r));
}
}  // namespace

void morphOpen(const cv::Mat& src, cv::Mat& dst, int ksize, KernelShape shape, cv::Mat& scratch)
{
  if (ksize < 3 || ksize % 2 == 0)
  {
    std::ostringstream s;
    s << "morphOpen: kernel size " << ksize << ": expected an odd size >= 3";
    throw std::invalid_argument(s.str());
  }
  if (src.data == dst.data)
    throw std::invalid_argument("morphOpen: dst must not alias src");
  if (shape != KernelShape::kRect)
  {
    const int cv_shape = shape == KernelShape::kCross ? cv::MORPH_CROSS : cv::MORPH_ELLIPSE;
    cv::morphologyEx(src, dst, cv::MORPH_OPEN, cv::getStructuringElement(cv_shape, cv::Size(ksize, ksize)));
    return;
  }
  switch (src.type())
  {
    case CV_8UC1:
      return openRect<std::uint8_t>(src, dst, ksize / 2, scratch);
    case CV_16UC1:
      return openRect<std::uint16_t>(src, dst, ksize / 2, scratch);
    case CV_32FC1:
      return openRect<float>(src, dst, ksize / 2, scratch);
    default:
      throw std::invalid_argument("morphOpen: image type " + cv::typeToString(src.type()) +
                                  ": expected 8UC1, 16UC1 or 32FC1");
  }
}

}  // namespace kinect_pipeline
#endif  // HWY_ONCE
