// The opening's row kernels (stages/opening_kernels.h), checked against OpenCV bit for bit. Design notes:
// docs/core_design.md ("Stage 1: the opening").
#include "kinect_pipeline/stages/opening_kernels.h"

#include <algorithm>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "base/simd.h"
#include "kinect_pipeline/model/encoding.h"

namespace kinect_pipeline
{
namespace detail
{
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
KP_CLONES void horizontal(const T* tmp, int w, int rad, T* dst)
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
struct MapOrder<T, true>
{
  static constexpr T kSmallest = DepthTraits<T>::kMinValid;
  static T key(T v) { return static_cast<T>(v - kSmallest); }
  static T back(T k)
  {
    return k > static_cast<T>(DepthTraits<T>::kNoReturn - kSmallest) ? DepthTraits<T>::kNoReturn
                                                                     : static_cast<T>(k + kSmallest);
  }
};

// The 3x3 case of rectRow / erodeMappedRow in one pass over the three source rows (a, b, c; repeated at the
// image's top and bottom), nine loads per pixel and no intermediate row: a row of vertical minima stored and
// read back at an offset of one pixel waits for the stores to reach the cache.
// The interior in blocks of a fixed 64 pixels (whole vectors, no scalar tail): the last block overlaps the one
// before it instead of leaving a remainder.
template <typename T, bool kMin, bool kMap>
KP_CLONES void box3Row(const T* __restrict a, const T* __restrict b, const T* __restrict c, int w, T* __restrict dst)
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

#if defined(KP_AVX512_PATHS)
#pragma GCC diagnostic push
#if !defined(__clang__)
// GCC 12's _mm512_alignr_epi32 passes _mm512_undefined_epi32() as its unused source: a false "may be used
// uninitialized".
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#endif
// box3Row of 8- and 16-bit rows with AVX-512: the column minima (maxima) of three rows once per pixel, in
// registers, and their neighbours by shifting the vector across its 128-bit lanes (alignr of 32-bit words, then
// of bytes) instead of loading six more rows' worth at offsets of one pixel. Min, max and the order key are exact:
// the same bits as box3Row. The row ends repeat their pixel (min(x, x) = x), as box3Row's ends leave it out.
template <typename T, bool kMin, bool kMap>
struct Box3Vector
{
  static constexpr int kLanes = 64 / sizeof(T);
  static constexpr int kSmallest = kMap ? DepthTraits<T>::kMinValid : 0;

  KP_TARGET_AVX512 static __m512i pick(__m512i x, __m512i y)
  {
    if constexpr (sizeof(T) == 1)
      return kMin ? _mm512_min_epu8(x, y) : _mm512_max_epu8(x, y);
    else
      return kMin ? _mm512_min_epu16(x, y) : _mm512_max_epu16(x, y);
  }
  KP_TARGET_AVX512 static __m512i key(const T* p)
  {
    const __m512i v = _mm512_loadu_si512(p);
    if constexpr (!kMap)
      return v;
    else if constexpr (sizeof(T) == 1)
      return _mm512_sub_epi8(v, _mm512_set1_epi8(kSmallest));
    else
      return _mm512_sub_epi16(v, _mm512_set1_epi16(kSmallest));
  }
  // MapOrder::back: keys above no-return - smallest were unknown values.
  KP_TARGET_AVX512 static __m512i back(__m512i k)
  {
    if constexpr (!kMap)
      return k;
    constexpr T none = DepthTraits<T>::kNoReturn;
    if constexpr (sizeof(T) == 1)
    {
      const __mmask64 unknown = _mm512_cmpgt_epu8_mask(k, _mm512_set1_epi8(static_cast<char>(none - kSmallest)));
      return _mm512_mask_mov_epi8(_mm512_add_epi8(k, _mm512_set1_epi8(kSmallest)), unknown,
                                  _mm512_set1_epi8(static_cast<char>(none)));
    }
    else
    {
      const __mmask32 unknown = _mm512_cmpgt_epu16_mask(k, _mm512_set1_epi16(static_cast<short>(none - kSmallest)));
      return _mm512_mask_mov_epi16(_mm512_add_epi16(k, _mm512_set1_epi16(kSmallest)), unknown,
                                   _mm512_set1_epi16(static_cast<short>(none)));
    }
  }
  KP_TARGET_AVX512 static __m512i column(const T* a, const T* b, const T* c, int u)
  {
    return pick(pick(key(a + u), key(b + u)), key(c + u));
  }
  // [prev's last pixel, cur's pixels but the last]: the left neighbours of cur's pixels.
  KP_TARGET_AVX512 static __m512i left(__m512i cur, __m512i prev)
  {
    return _mm512_alignr_epi8(cur, _mm512_alignr_epi32(cur, prev, 12), 16 - sizeof(T));
  }
  // [cur's pixels but the first, next's first pixel]: the right neighbours.
  KP_TARGET_AVX512 static __m512i right(__m512i cur, __m512i next)
  {
    return _mm512_alignr_epi8(_mm512_alignr_epi32(next, cur, 4), cur, sizeof(T));
  }
  // The column of pixel u alone (as box3Row's), in every lane.
  KP_TARGET_AVX512 static __m512i splatColumn(const T* a, const T* b, const T* c, int u)
  {
    using O = MapOrder<T, kMap>;
    const T v = detail::pick<kMin>(detail::pick<kMin>(O::key(a[u]), O::key(b[u])), O::key(c[u]));
    if constexpr (sizeof(T) == 1)
      return _mm512_set1_epi8(static_cast<char>(v));
    else
      return _mm512_set1_epi16(static_cast<short>(v));
  }

  // w >= kLanes. Whole vectors, then the last kLanes pixels once more (the same values where they overlap).
  KP_TARGET_AVX512 static void row(const T* a, const T* b, const T* c, int w, T* dst)
  {
    const int full = w / kLanes * kLanes;
    __m512i cur = column(a, b, c, 0);
    __m512i prev = splatColumn(a, b, c, 0);
    for (int u = 0; u < full; u += kLanes)
    {
      // The next whole vector, or (the last one) the pixel after this vector or the row's last pixel repeated.
      const __m512i next = u + 2 * kLanes <= w ? column(a, b, c, u + kLanes)
                                               : splatColumn(a, b, c, std::min(u + kLanes, w - 1));
      _mm512_storeu_si512(dst + u, back(pick(pick(left(cur, prev), cur), right(cur, next))));
      prev = cur;
      cur = next;
    }
    if (full < w)
    {
      const int u = w - kLanes;  // >= 1
      const __m512i x = column(a, b, c, u);
      const __m512i m = pick(pick(column(a, b, c, u - 1), x), right(x, splatColumn(a, b, c, w - 1)));
      _mm512_storeu_si512(dst + u, back(m));
    }
  }
};
#pragma GCC diagnostic pop
#endif

// box3Row from the three rows given (w >= 3), with AVX-512 where the CPU has it and vector is on (8- and 16-bit rows).
template <typename T, bool kMin, bool kMap>
void box3Rows(const T* a, const T* b, const T* c, int w, T* dst, bool vector)
{
#if defined(KP_AVX512_PATHS)
  if constexpr (!std::is_floating_point_v<T>)
  {
    if (vector && w >= Box3Vector<T, kMin, kMap>::kLanes && vectorPathsSupported())
      return Box3Vector<T, kMin, kMap>::row(a, b, c, w, dst);
  }
#else
  (void)vector;
#endif
  box3Row<T, kMin, kMap>(a, b, c, w, dst);
}

// box3Rows of row r of src and its neighbours (the row itself at the image's top and bottom).
template <typename T, bool kMin, bool kMap>
void box3(const cv::Mat& src, int r, T* dst, bool vector)
{
  const T* b = src.ptr<T>(r);
  const T* a = r > 0 ? src.ptr<T>(r - 1) : b;
  const T* c = r + 1 < src.rows ? src.ptr<T>(r + 1) : b;
  box3Rows<T, kMin, kMap>(a, b, c, src.cols, dst, vector);
}
}  // namespace

template <typename T, bool kMin>
KP_CLONES void rectRow(const cv::Mat& src, int r, int rad, T* tmp, T* dst, bool vector)
{
  const int w = src.cols;
  if (rad == 1 && w >= 3)
    return box3<T, kMin, false>(src, r, dst, vector);
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
void dilate3Rows(const T* a, const T* b, const T* c, int w, T* dst, bool vector)
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
  box3Rows<T, false, false>(a, b, c, w, dst, vector);
}

template <typename T>
KP_CLONES void erodeMappedRow(const cv::Mat& src, int r, int rad, T* tmp, T* dst, bool vector)
{
  using Tr = DepthTraits<T>;
  const int w = src.cols;
  // Floats: mapping each of the nine loads costs more than the separable passes' wait (no cheap order key).
  if constexpr (!std::is_floating_point_v<T>)
    if (rad == 1 && w >= 3)
      return box3<T, true, true>(src, r, dst, vector);
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

#define KP_INSTANTIATE(T)                                                       \
  template void rectRow<T, true>(const cv::Mat&, int, int, T*, T*, bool);       \
  template void rectRow<T, false>(const cv::Mat&, int, int, T*, T*, bool);      \
  template void erodeMappedRow<T>(const cv::Mat&, int, int, T*, T*, bool);     \
  template void dilate3Rows<T>(const T*, const T*, const T*, int, T*, bool);
KP_INSTANTIATE(std::uint8_t)
KP_INSTANTIATE(std::uint16_t)
KP_INSTANTIATE(float)
#undef KP_INSTANTIATE
}  // namespace detail

namespace
{
template <typename T>
void openRect(const cv::Mat& src, cv::Mat& dst, int rad, cv::Mat& scratch, bool vector)
{
  scratch.create(src.size(), src.type());
  dst.create(src.size(), src.type());
  std::vector<T> tmp(src.cols);
  for (int r = 0; r < src.rows; ++r)
    detail::rectRow<T, true>(src, r, rad, tmp.data(), scratch.ptr<T>(r), vector);
  for (int r = 0; r < src.rows; ++r)
    detail::rectRow<T, false>(scratch, r, rad, tmp.data(), dst.ptr<T>(r), vector);
}
}  // namespace

void morphOpen(const cv::Mat& src, cv::Mat& dst, int ksize, KernelShape shape, cv::Mat& scratch, bool vector)
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
      return openRect<std::uint8_t>(src, dst, ksize / 2, scratch, vector);
    case CV_16UC1:
      return openRect<std::uint16_t>(src, dst, ksize / 2, scratch, vector);
    case CV_32FC1:
      return openRect<float>(src, dst, ksize / 2, scratch, vector);
    default:
      throw std::invalid_argument("morphOpen: image type " + cv::typeToString(src.type()) +
                                  ": expected 8UC1, 16UC1 or 32FC1");
  }
}

}  // namespace kinect_pipeline
