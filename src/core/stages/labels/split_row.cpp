// The SIMD kernel of the labelling by value (stages/labels/split_row.h), compiled once per target: the compares
// as masks, labels and flags built from them, counts by the masks' popcounts. Design notes:
// docs/core_design.md ("SIMD kernels and their references").
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "stages/labels/split_row.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "stages/labels/split_row.h"

#include <cstdint>
#include <type_traits>

#include "kinect_pipeline/model/encoding.h"

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
// Where pixels of one label first appear (their column) and last appear (the last block holding one: its column
// is found from the row's data at the end). No mask is kept: SVE's masks cannot be members.
struct Track
{
  int first = -1, at = -1;
  template <class D, class M>
  HWY_INLINE void add(D d, M m, int u)
  {
    if (hn::AllFalse(d, m))
      return;
    if (first < 0)
      first = u + static_cast<int>(hn::FindFirstTrue(d, m));
    at = u;
  }
  /** The last column of the block at `at` (L columns) where is(column) holds, -1 for none. */
  template <typename Is>
  int last(int L, const Is& is) const
  {
    if (at >= 0)
      for (int u = at + L - 1; u >= at; --u)
        if (is(u))
          return u;
    return -1;
  }
};

// v >= t, unsigned: one mask compare on AVX-512 (Highway 1.0 has no unsigned >=: its Not(Lt) adds a mask negation,
// frames 1-2 % slower); elsewhere max and an equality (x86 before AVX-512 has no unsigned compare: Highway's takes
// three or four instructions).
template <class V>
HWY_INLINE auto atLeast(V v, V t)
{
#if HWY_TARGET == HWY_AVX3
  using T = hn::TFromV<V>;
  if constexpr (sizeof(T) == 1)
    return hn::Mask512<T>{_mm512_cmpge_epu8_mask(v.raw, t.raw)};
  else
    return hn::Mask512<T>{_mm512_cmpge_epu16_mask(v.raw, t.raw)};
#else
  return hn::Eq(hn::Max(v, t), v);
#endif
}

// Stores a vector of small values (labels, flags) as bytes.
template <class D, class V>
HWY_INLINE void storeBytes(D d, V v, std::uint8_t* p)
{
  if constexpr (sizeof(hn::TFromD<D>) == 1)
    hn::StoreU(v, d, p);
#if HWY_TARGET == HWY_AVX3
  else  // one truncating move (vpmovwb)
    _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), _mm512_cvtepi16_epi8(v.raw));
#else
  else
  {
    const hn::Rebind<std::uint8_t, D> d8;
    hn::StoreU(hn::DemoteTo(d8, hn::BitCast(hn::RebindToSigned<D>(), v)), d8, p);  // values below 128
  }
#endif
}

// The counts are written into c, not returned: the wrapper's copy of a returned RowCounts read it back in 32-byte
// loads, which wait for the field-by-field stores to retire (a store-forwarding stall: frames 2-4 % slower).
template <typename T, bool kRescue>
void splitRowV(const T* src, int w, const ValueSplit& s, std::uint8_t* lab, T* dst, const T* in, std::uint8_t* cand,
               RowCounts& c)
{
  using Tr = DepthTraits<T>;
  const hn::ScalableTag<T> d;
  using D = decltype(d);
  const int L = static_cast<int>(hn::Lanes(d));
  constexpr T none = Tr::kNoReturn;
  const bool rescuable = s.t1 < none && (s.l1 == kFloor || s.l1 == kAboveCeiling);
  const auto set = [&](int x) { return hn::Set(d, static_cast<T>(x)); };
  const auto t1 = set(s.t1), t2 = set(s.t2), vnone = set(none), rt1 = set(rescuable ? s.t1 : none);
  const auto minvalid = set(Tr::kMinValid), move1 = set(s.min_move - 1);
  const auto l1 = set(s.l1), l2 = set(s.l2), linv = set(kInvalid), lkept = set(kKept), lbelow = set(kBelowFloor);
  const auto one = set(1);
  int n1 = 0, n2 = 0, ni = 0, nc = 0;
  Track kept, below;
  // One block of L pixels from u (counted: the lanes not counted yet; all of them but in the last block).
  const auto block = [&](int u, auto whole, hn::Mask<D> counted) {
    const auto count = [&](int& n, hn::Mask<D> m) {  // a popcount of the mask's bits
      if constexpr (!decltype(whole)::value)
        m = hn::And(m, counted);
      n += static_cast<int>(hn::CountTrue(d, m));
    };
    const auto v = hn::LoadU(d, src + u);
    // The raw row before the stores: a frame's 8-bit input, labels and cleaned image are alike in size and may lie at
    // one offset in their pages (they did in the bench), and a load after a store to that offset waits (4K aliasing).
    const auto raw = kRescue ? hn::LoadU(d, in + u) : v;
    const auto g1 = atLeast(v, t1), g2 = atLeast(v, t2), inv = hn::Eq(v, vnone);
    if constexpr (sizeof(T) == 1)
      hn::StoreU(hn::IfThenElse(g1, vnone, v), d, dst + u);  // removed: 255
    else
      hn::StoreU(hn::IfThenZeroElse(g1, v), d, dst + u);  // removed: 0
    // l1 from t1, + l2 from t2, no return kInvalid (it is >= t1 and >= t2).
    const auto l = hn::IfThenElse(inv, linv, hn::Add(hn::IfThenElseZero(g1, l1), hn::IfThenElseZero(g2, l2)));
    storeBytes(d, l, lab + u);
    count(n1, g1);
    count(n2, g2);
    count(ni, inv);
    const auto is_below = hn::Eq(l, lbelow);
    kept.add(d, hn::Not(g1), u);  // kept: below t1
    below.add(d, is_below, u);
    if constexpr (kRescue)
    {
      const auto mapped = hn::IfThenElse(hn::Lt(raw, minvalid), vnone, raw);     // DepthTraits::map
      const auto above = hn::Gt(mapped, hn::SaturatedAdd(v, move1));               // raw - v >= min_move
      const auto inband = hn::AndNot(atLeast(mapped, t2), atLeast(mapped, rt1));  // rt1 <= raw < t2
      const auto f = hn::And(hn::Or(hn::Eq(l, lkept), is_below), hn::And(above, inband));
      storeBytes(d, hn::IfThenElseZero(f, one), cand + u);
      count(nc, f);
    }
  };
  int u = 0;
  const auto all = hn::FirstN(d, static_cast<std::size_t>(L));
  for (; u + L <= w; u += L)
    block(u, std::true_type(), all);
  if (u < w)  // the last L pixels again: the lanes before u are counted already
    block(w - L, std::false_type(), hn::Not(hn::FirstN(d, static_cast<std::size_t>(u - (w - L)))));
  c = splitCounts(s, w, n1, n2, ni, nc);
  c.kept_first = kept.first;
  const T t1v = static_cast<T>(s.t1);
  c.kept_last = kept.last(L, [&](int u) { return src[u] < t1v; });
  c.below_first = below.first;
  c.below_last = below.last(L, [&](int u) { return lab[u] == kBelowFloor; });
}
}  // namespace

// @return false (nothing written) for a row narrower than a vector, and on the one-lane scalar target, where the
// plain loop (by_value.cpp), which the compiler vectorises for the baseline, takes 30 % less of a frame.
template <typename T>
bool splitRow(const T* src, int w, const ValueSplit& s, std::uint8_t* lab, T* dst, const T* in,
              std::uint8_t* cand, RowCounts& c)
{
  if (HWY_TARGET == HWY_SCALAR || w < static_cast<int>(hn::Lanes(hn::ScalableTag<T>())))
    return false;
  if (in)
    splitRowV<T, true>(src, w, s, lab, dst, in, cand, c);
  else
    splitRowV<T, false>(src, w, s, lab, dst, in, cand, c);
  return true;
}
bool splitRow8(const std::uint8_t* src, int w, const ValueSplit& s, std::uint8_t* lab, std::uint8_t* dst,
               const std::uint8_t* in, std::uint8_t* cand, RowCounts& c)
{
  return splitRow(src, w, s, lab, dst, in, cand, c);
}
bool splitRow16(const std::uint16_t* src, int w, const ValueSplit& s, std::uint8_t* lab, std::uint16_t* dst,
                const std::uint16_t* in, std::uint8_t* cand, RowCounts& c)
{
  return splitRow(src, w, s, lab, dst, in, cand, c);
}
}  // namespace HWY_NAMESPACE
}  // namespace detail
}  // namespace kinect_pipeline
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kinect_pipeline
{
namespace detail
{
HWY_EXPORT(splitRow8);
HWY_EXPORT(splitRow16);

template <>
bool splitRowSimd<std::uint8_t>(const std::uint8_t* src, int w, const ValueSplit& s, std::uint8_t* lab,
                                std::uint8_t* dst, const std::uint8_t* in, std::uint8_t* cand, RowCounts& c)
{
  return HWY_DYNAMIC_DISPATCH(splitRow8)(src, w, s, lab, dst, in, cand, c);
}
template <>
bool splitRowSimd<std::uint16_t>(const std::uint16_t* src, int w, const ValueSplit& s, std::uint8_t* lab,
                                 std::uint16_t* dst, const std::uint16_t* in, std::uint8_t* cand, RowCounts& c)
{
  return HWY_DYNAMIC_DISPATCH(splitRow16)(src, w, s, lab, dst, in, cand, c);
}
}  // namespace detail
}  // namespace kinect_pipeline
#endif  // HWY_ONCE
