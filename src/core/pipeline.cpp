#include "kinect_pipeline/pipeline.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgproc.hpp>
#ifdef _OPENMP
#include <omp.h>
#endif

#include "kinect_pipeline/morphology.h"
#include "simd.h"

namespace kinect_pipeline
{
namespace
{
constexpr float kInf = std::numeric_limits<float>::infinity();
constexpr double kHalfPi = 1.57079632679489661923;

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); }

int defaultThreads()
{
#ifdef _OPENMP
  return omp_get_max_threads();
#else
  return 1;
#endif
}

int threadId()
{
#ifdef _OPENMP
  return omp_get_thread_num();
#else
  return 0;
#endif
}

// Rows of a chunk of the row loop (a thread's unit of work): their bins are planned together.
constexpr int kRowChunk = 8;

// Metres per unit of each encoding (8-bit: max_depth / 255).
template <typename T>
float depthScale(double max_depth)
{
  if constexpr (std::is_same_v<T, std::uint8_t>)
    return static_cast<float>(max_depth / 255.0);
  else if constexpr (std::is_same_v<T, std::uint16_t>)
    return 0.001f;
  else
    return 1.0f;
}

struct RowCounts
{
  int kept = 0, invalid = 0, floor = 0, ceiling = 0;
  int candidates = 0;  // pixels flagged for the rescue (classifyRow)
  // First and last kept and below-floor column where the labelling found them on its way (-1: not known).
  int kept_first = -1, kept_last = -1, below_first = -1, below_last = -1;
};

/**
 * The plane removal of one pixel of (mapped) value v with threshold t [m] and rise (col[u] + rise_row): exclusive
 * classes, kept if none; @return its label. The one definition, inlined into classifyRow's vectorised loop and
 * used for single values (ValueLabeler). Outputs by reference: a returned struct stops the vectoriser.
 */
template <typename T>
__attribute__((always_inline)) inline std::uint8_t classifyPixel(T v, float t, float rise, float scale, float floor_h,
                                                                 float ceil_h, float& d, bool& keep, bool& below)
{
  d = static_cast<float>(v) * scale;
  const float e = d * rise;
  const float above = e + floor_h;  // height above the floor (exact geometry)
  const float band = t * rise;      // -t * |rise| where the ray meets the floor
  const bool down = rise < 0.0f;
  // Exclusive masks combined arithmetically (a select chain would not vectorise).
  const bool inv = DepthTraits<T>::isNoReturn(v);
  const bool ceil = !inv & (e > ceil_h);
  below = !inv & !ceil & down & (above < band);
  const bool floor = !inv & !ceil & !below & down & (above < -band);
  keep = !(inv | ceil | below | floor);
  return static_cast<std::uint8_t>(inv * kInvalid + ceil * kAboveCeiling + below * kBelowFloor + floor * kFloor);
}

/**
 * Plane removal of one row: labels and cleaned depth, and the flags of the pixels the rescue (below) may relabel:
 * kept or below the floor, with a raw depth (in) that the opening moved nearer by more than t(opened depth) =
 * t[u], a superset of those it relabels (t(raw) >= t(opened): the table is non-decreasing; the difference is
 * computed as rescuePixel computes it). Without kRescue (nothing was opened) in and cand are not used.
 * Branch-free, with restrict pointers, so that the compiler vectorises it.
 * @param rise_row the row's term of the rise per metre of depth (col[u] + rise_row < 0: the ray goes down)
 */
template <typename T, bool kRescue>
KP_CLONES RowCounts classifyRow(const T* __restrict src, const T* __restrict in, const float* __restrict t,
                                const float* __restrict col, float rise_row, float scale, float floor_h, float ceil_h,
                                int w, std::uint8_t* __restrict lab, T* __restrict dst, std::uint8_t* __restrict cand)
{
  using Tr = DepthTraits<T>;
  const T removed = Tr::removed();
  int n_kept = 0, n_invalid = 0, n_floor = 0, n_ceiling = 0, n_cand = 0;
  for (int u = 0; u < w; ++u)
  {
    const T v = src[u];
    float d;
    bool keep, below;
    const std::uint8_t l = classifyPixel(v, t[u], col[u] + rise_row, scale, floor_h, ceil_h, d, keep, below);
    lab[u] = l;
    dst[u] = keep ? v : removed;
    if constexpr (kRescue)
    {
      // From the unmapped raw value (unknown ones are 0 or below: moved < 0; or no return): a select before the
      // conversion would stop the vectoriser.
      const T raw = in[u];
      const float moved = static_cast<float>(raw) * scale - d;
      const bool flag = (keep | below) & !Tr::isNoReturn(raw) & (moved > t[u]);
      cand[u] = flag;
      n_cand += flag;
    }
    n_kept += keep;
    n_invalid += l == kInvalid;
    n_floor += l == kFloor;
    n_ceiling += l == kAboveCeiling;
  }
  return {n_kept, n_invalid, n_floor, n_ceiling, n_cand};
}

/**
 * The opening can only move a depth nearer (a max of mins). Where it moved a pixel by more than t(d) and the raw
 * depth shows it on the floor or beyond the ceiling plane (at the corner of an object, or far down the floor where
 * a row spans metres), the raw depth decides: such a pixel is floor / above the ceiling plane, not an obstacle.
 * (Not "below the floor": beyond an object's silhouette that would turn noisy far floor into cliffs; at the rim of
 * a hole the opening leaves an obstacle pixel, which errs on the safe side.)
 * @param in the input row (unmapped), @param src the opened row
 */
// The rescue of one pixel (above): @return true if it relabelled the pixel.
template <typename T>
inline bool rescuePixel(int u, const T* in, const T* src, const ThresholdLut& lut, const float* col, float rise_row,
                        float scale, float floor_h, float ceil_h, std::uint8_t* lab, T* dst, RowCounts& c)
{
  using Tr = DepthTraits<T>;
  if (lab[u] != kKept && lab[u] != kBelowFloor)
    return false;
  const T raw = Tr::map(in[u]);
  if (raw == src[u] || Tr::isNoReturn(raw))
    return false;
  const float d = static_cast<float>(raw) * scale;
  float t;
  if constexpr (std::is_same_v<T, std::uint8_t>)
    t = lut.forValue(raw);
  else
    t = lut.forDepth(d);
  // Only where the opening moved the pixel by more than the noise band: not the noise of a low obstacle.
  if (!(d - static_cast<float>(src[u]) * scale > t))
    return false;
  const float rise = col[u] + rise_row;
  const float e = d * rise;
  const float above = e + floor_h;
  std::uint8_t label;
  if (e > ceil_h)
    label = kAboveCeiling;
  else if (rise < 0.0f && above < -t * rise && above > t * rise)
    label = kFloor;
  else
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

// The rescue on the pixels flagged in cand only (a superset of those it relabels): 8 flags (0/1 bytes) at a time,
// then their set bytes.
template <typename T>
void rescueCandidates(const std::uint8_t* cand, const T* in, const T* src, const ThresholdLut& lut,
                      const float* col, float rise_row, float scale, float floor_h, float ceil_h, int w,
                      std::uint8_t* lab, T* dst, RowCounts& c)
{
  const int full = w & ~7;
  for (int u0 = 0; u0 < full; u0 += 8)
  {
    std::uint64_t x;
    std::memcpy(&x, cand + u0, 8);
    for (; x != 0; x &= x - 1)
      rescuePixel<T>(u0 + __builtin_ctzll(x) / 8, in, src, lut, col, rise_row, scale, floor_h, ceil_h, lab, dst, c);
  }
  for (int u = full; u < w; ++u)
    if (cand[u])
      rescuePixel<T>(u, in, src, lut, col, rise_row, scale, floor_h, ceil_h, lab, dst, c);
}

template <typename T>
KP_CLONES void thresholdRow(const T* __restrict src, const ThresholdLut& lut, float scale, int w, float* __restrict t)
{
  // A gather, which SSE cannot vectorise: kept out of classifyRow.
  for (int u = 0; u < w; ++u)
  {
    if constexpr (std::is_same_v<T, std::uint8_t>)
      t[u] = lut.forValue(src[u]);
    else if constexpr (std::is_same_v<T, std::uint16_t>)
      t[u] = lut.forMillimetres(src[u]);  // scale is 0.001f
    else
      t[u] = lut.forDepth(static_cast<float>(src[u]) * scale);
  }
}

/**
 * An 8- or 16-bit row whose pixels all have the same rise (no roll) has labels that depend on the value alone.
 * Where they are monotone in the value (kept, floor, below floor; or kept, above ceiling), two integer compares
 * per pixel classify the row: a value v below the no-return value is kept below t1, labelled l1 from t1 and
 * l1 + l2 from t2 (the no-return value: no such value).
 */
struct ValueSplit
{
  int t1 = 0, t2 = 0;
  std::uint8_t l1 = 0, l2 = 0;
  int min_move = 1;  // the rescue's flags: raw values at least this many values above the opened one (rescueMove)
};

/**
 * The table's terms of ValueProof over the values 0 .. no-return - 1, with d = fl(v scale) as the pixels get it.
 * @param table the threshold of each value (ThresholdLut::valueTable)
 */
template <typename T>
detail::ValueTerms valueTerms(const float* table, float scale)
{
  constexpr int last = DepthTraits<T>::kNoReturn - 1;
  constexpr int window = detail::ValueTerms::kValueWindow;
  detail::ValueTerms t;
  t.nondecreasing = true;
  std::vector<double> g(last + 1);  // d - t of each value
  for (int v = 0; v <= last; ++v)
  {
    g[v] = static_cast<double>(static_cast<float>(v) * scale) - table[v];
    if (v > 0)
      t.nondecreasing = t.nondecreasing && table[v] >= table[v - 1];
  }
  t.gap_min = std::numeric_limits<double>::infinity();
  for (int v = 0; v < last; ++v)
    t.gap_min = std::min(t.gap_min, g[v + 1] - g[v]);
  // From the top: suffix minimum of g, against each value window below it.
  t.gap_window = std::numeric_limits<double>::infinity();
  double suffix = std::numeric_limits<double>::infinity();
  for (int v = last; v >= window; --v)
  {
    suffix = std::min(suffix, g[v]);
    t.gap_window = std::min(t.gap_window, suffix - g[v - window]);
  }
  t.d_max = static_cast<float>(last) * scale;
  t.t_max = table[last];
  return t;
}

/**
 * When the labels of a row's values are provably monotone in the value, so that value thresholds found by a
 * search give every value's label. With rise R (the same for the whole row), d = fl(v scale), t = table[v]:
 * - above ceiling, fl(d R) > ceil_h: fl(d R) is monotone in v, so is the test.
 * - floor or below (R < 0), fl(fl(d R) + floor_h) < -fl(t R): the left side does not grow with v, the right side
 *   does not shrink (t does not decrease), so once true it stays true.
 * - below (R < 0), fl(fl(d R) + floor_h) < fl(t R): differs from G = floor_h + (d - t) R by at most
 *   eta = u (2.01 |d R| + floor_h + |t R|); if d - t grows by at least gap_min from one value to the next,
 *   G falls by gap_min |R| and the test is monotone when gap_min |R| >= 2 eta; and it is never true when
 *   floor_h - d_max |R| > eta.
 * A 16-bit table in 1 cm cells steps up at each cell border, by more than a value's 1 mm where t(d) grows by more
 * than 1 mm per cm (the default curve beyond 6 m): d - t then dips by a little at each border. It still grows by
 * gap_window from any value to every value kValueWindow above it, so when gap_window |R| >= 2 eta the test
 * can only change more than once within kValueWindow values of where the search found it changing (windowed):
 * the values there are labelled one by one, and if any disagrees the row is labelled as when not monotone.
 */
enum class Monotone
{
  kNo,
  kYes,
  kWindowed,
};

struct ValueProof
{
  bool ok = false;  // table non-decreasing, ceil_h >= 0, floor_h > 0
  detail::ValueTerms table;
  double floor_h = 0.0;

  void build(const detail::ValueTerms& terms, float floor_h_, float ceil_h)
  {
    table = terms;
    ok = terms.nondecreasing && ceil_h >= 0.0f && floor_h_ > 0.0f;
    floor_h = floor_h_;
  }
  Monotone monotone(float rise) const
  {
    if (!ok)
      return Monotone::kNo;
    if (!(rise < 0.0f))
      return Monotone::kYes;  // kept, then above ceiling
    const double r = -static_cast<double>(rise), u = 1.0 / 16777216.0;
    const double eta = 1.01 * u * (2.01 * table.d_max * r + floor_h + table.t_max * r);
    if (table.gap_min * r >= 2.0 * eta || floor_h - table.d_max * r > eta)
      return Monotone::kYes;
    return table.gap_window * r >= 2.0 * eta ? Monotone::kWindowed : Monotone::kNo;
  }
};

/** Labels single values with classifyPixel, as classifyRow labels pixels: the same labels, bit for bit. */
template <typename T>
struct ValueLabeler
{
  const std::uint8_t* values;  // 8-bit: 0, 1, ..., 255 (labelled all at once when not monotone); 16-bit: unused
  const float *table, *colc;   // the threshold of each value (ThresholdLut::valueTable); 256 copies of the column term
  float rise_row, scale, floor_h, ceil_h;

  std::uint8_t operator()(int v) const
  {
    float d;
    bool keep, below;
    return classifyPixel(static_cast<T>(v), table[v], colc[0] + rise_row, scale, floor_h, ceil_h, d, keep, below);
  }
};

// First v in [lo, hi] with pred(v) (monotone: false, then true), or hi + 1; searched from a guess outwards.
template <typename Pred>
int firstTrue(const Pred& pred, int lo, int hi, int guess)
{
  guess = std::min(std::max(guess, lo), hi);
  int a, b;  // pred false below a (or a == lo), true from b (or b == hi + 1); answer in [a, b]
  if (guess <= hi && pred(guess))
  {
    b = guess;
    int step = 1;
    a = guess - 1;
    while (a >= lo && pred(a))
    {
      b = a;
      a -= step;
      step *= 2;
    }
    a = std::max(a + 1, lo);
  }
  else
  {
    a = guess + 1;
    int step = 1;
    b = guess + 1;
    while (b <= hi && !pred(b))
    {
      a = b + 1;
      b += step;
      step *= 2;
    }
    b = std::min(b, hi + 1);
  }
  while (a < b)  // pred false before a, true at b (or b == hi + 1)
  {
    const int m = a + (b - a) / 2;
    if (pred(m))
      b = m;
    else
      a = m + 1;
  }
  return b;
}

/**
 * Where a row's labels are expected to change, as a starting point for the search (any start gives the same
 * thresholds): the floor band starts where d + t(d) reaches the depth D = floor_h / -R at which the row's rays
 * meet the floor and ends where d - t(d) does (t taken at the first guess); the ceiling plane is at ceil_h / R.
 */
template <typename T>
void predictSplit(const ValueLabeler<T>& label, int lo, int hi, int& g1, int& g2)
{
  // A guess: float arithmetic and one division (the row loop waits for it).
  const float rise = label.colc[0] + label.rise_row, inv_scale = 1.0f / label.scale;
  const auto value = [&](float x) { return !(x >= lo) ? lo : (x > hi ? hi : static_cast<int>(x)); };  // NaN: lo
  if (rise < 0.0f)
  {
    const float floor_at = label.floor_h / (-rise * label.scale);  // [values]
    const float t = label.table[value(floor_at)] * inv_scale;
    g1 = value(floor_at - label.table[value(floor_at - t)] * inv_scale);
    g2 = value(floor_at + label.table[value(floor_at + t)] * inv_scale);
  }
  else
  {
    g1 = rise > 0.0f ? value(label.ceil_h / (rise * label.scale)) : hi;
    g2 = hi;
  }
}

/**
 * Monotone::kWindowed: where the below-floor test changes (t2, or t1 if the first removed value is below the floor;
 * hi + 1 if it never does), whether each value of the window either side has the label the split gives it.
 */
template <typename T>
bool windowAgrees(const ValueLabeler<T>& label, const ValueSplit& split, int hi)
{
  int c;
  if (split.l1 == kBelowFloor)
    c = split.t1;
  else if (split.l1 == kFloor)
    c = std::min(split.t2, hi + 1);
  else
    return true;  // kept, then above ceiling
  const int w = detail::ValueTerms::kValueWindow;
  for (int v = std::max(split.t1, c - w); v <= std::min(hi, c + w - 1); ++v)
  {
    const int expect = v < split.t2 ? split.l1 : split.l1 + split.l2;
    if (label(v) != expect)
      return false;
  }
  return true;
}

/**
 * The value thresholds of a row with values lo..hi (< no-return), searched from where the planes predict them if
 * the labels are provably monotone, else (8-bit) from every value's label. @return false if they are not monotone
 * at all, or (16-bit) not provably so.
 */
template <typename T>
bool splitValues(const ValueLabeler<T>& label, const ValueProof& proof, int lo, int hi, std::uint8_t* lab,
                 std::uint8_t* dst, ValueSplit& out)
{
  out = ValueSplit{DepthTraits<T>::kNoReturn, DepthTraits<T>::kNoReturn, 0, 0};
  if (lo > hi)
    return true;
  const Monotone monotone = proof.monotone(label.colc[0] + label.rise_row);  // the row's whole rise
  if (monotone != Monotone::kNo)
  {
    int g1, g2;
    predictSplit(label, lo, hi, g1, g2);
    const int t1 = firstTrue([&](int v) { return label(v) != kKept; }, lo, hi, g1);
    if (t1 <= hi)
    {
      out.t1 = t1;
      out.l1 = label(t1);
      if (out.l1 == kFloor)
      {
        const int t2 = firstTrue([&](int v) { return label(v) == kBelowFloor; }, t1, hi, g2);
        if (t2 <= hi)
        {
          out.t2 = t2;
          out.l2 = kBelowFloor - kFloor;
        }
      }
    }
    if (monotone == Monotone::kYes || windowAgrees(label, out, hi))
      return true;
    out = ValueSplit{DepthTraits<T>::kNoReturn, DepthTraits<T>::kNoReturn, 0, 0};
  }
  if constexpr (!std::is_same_v<T, std::uint8_t>)
  {
    return false;  // 65535 values: the row is labelled pixel by pixel
  }
  else
  {
    const int n = hi - lo + 1;
    classifyRow<std::uint8_t, false>(label.values + lo, nullptr, label.table + lo, label.colc, label.rise_row,
                                     label.scale, label.floor_h, label.ceil_h, n, lab, dst, nullptr);
    int i = 0;
    while (i < n && lab[i] == kKept)
      ++i;
    if (i == n)
      return true;
    out.t1 = lo + i;
    out.l1 = lab[i];
    while (i < n && lab[i] == out.l1)
      ++i;
    if (i == n)
      return true;
    const std::uint8_t l = lab[i];
    if (l < out.l1)
      return false;
    out.t2 = lo + i;
    out.l2 = static_cast<std::uint8_t>(l - out.l1);
    while (i < n && lab[i] == l)
      ++i;
    return i == n;
  }
}

// A row's counts from those of its values at or above t1 (n1) and t2 (n2), of no return (ni) and of the rescue's
// flags (nc).
inline RowCounts splitCounts(const ValueSplit& s, int w, int n1, int n2, int ni, int nc)
{
  RowCounts c;
  c.kept = w - n1;
  c.invalid = ni;
  // n1 - n2 pixels have label l1; the no-return values count in n1 and n2 alike.
  c.floor = s.l1 == kFloor ? n1 - n2 : 0;
  c.ceiling = s.l1 == kAboveCeiling ? n1 - n2 : 0;
  c.candidates = nc;
  return c;
}

// Labels, cleaned depth and counts of an 8- or 16-bit row from its value thresholds. Integer arithmetic of the
// pixel's width only, with counters of that width per block of 128 pixels (a multiple of every vector width), so
// that it vectorises without a scalar tail. With in (the raw row), also flags in cand the pixels the rescue may
// relabel: kept or below floor, moved nearer by the opening, and whose raw value has the label floor or above
// ceiling (values rt1 <= v < rt2).
template <typename T>
KP_CLONES RowCounts splitRow(const T* __restrict src, int w, const ValueSplit& s, std::uint8_t* __restrict lab,
                             T* __restrict dst, const T* __restrict in, std::uint8_t* __restrict cand)
{
  using Tr = DepthTraits<T>;
  constexpr T none = Tr::kNoReturn;
  const T t1 = static_cast<T>(s.t1), t2 = static_cast<T>(s.t2), l1 = s.l1, l2 = s.l2;
  // The no-return value is >= t1 and >= t2: its l1 + l2 becomes kInvalid.
  const T fix = static_cast<T>(l1 + l2 - kInvalid);
  const bool rescuable = s.t1 < none && (s.l1 == kFloor || s.l1 == kAboveCeiling);
  const T rt1 = rescuable ? t1 : none, rt2 = t2;
  const int move = s.min_move;
  int n1 = 0, n2 = 0, ni = 0, nc = 0;
  for (int u0 = 0; u0 < w; u0 += 128)
  {
    const int u1 = std::min(w, u0 + 128);
    T c1 = 0, c2 = 0, ci = 0, cc = 0;
    if (in)
    {
      for (int u = u0; u < u1; ++u)
      {
        const T v = src[u];
        const T g1 = v >= t1, g2 = v >= t2, inv = v == none;
        const T l = static_cast<T>(g1 * l1 + g2 * l2 - inv * fix);
        lab[u] = static_cast<std::uint8_t>(l);
        if constexpr (std::is_same_v<T, std::uint8_t>)
          dst[u] = static_cast<T>(v | -g1);  // removed: 255
        else
          dst[u] = static_cast<T>(v & (g1 - 1));  // removed: 0
        c1 += g1;
        c2 += g2;
        ci += inv;
        const T raw = Tr::map(in[u]);
        const T f = static_cast<T>(((l == kKept) | (l == kBelowFloor)) & (raw - v >= move) & (raw >= rt1) & (raw < rt2));
        cand[u] = static_cast<std::uint8_t>(f);
        cc += f;
      }
    }
    else
    {
      for (int u = u0; u < u1; ++u)
      {
        const T v = src[u];
        const T g1 = v >= t1, g2 = v >= t2, inv = v == none;
        lab[u] = static_cast<std::uint8_t>(g1 * l1 + g2 * l2 - inv * fix);
        if constexpr (std::is_same_v<T, std::uint8_t>)
          dst[u] = static_cast<T>(v | -g1);
        else
          dst[u] = static_cast<T>(v & (g1 - 1));
        c1 += g1;
        c2 += g2;
        ci += inv;
      }
    }
    n1 += c1;
    n2 += c2;
    ni += ci;
    nc += cc;
  }
  return splitCounts(s, w, n1, n2, ni, nc);
}

#if defined(KP_AVX512_PATHS)
#pragma GCC diagnostic push
// 64-byte vectors pass only between functions inlined into splitRow512: no call has the ABI the warning is about.
#pragma GCC diagnostic ignored "-Wpsabi"
#if !defined(__clang__)
// GCC 12's 512-to-256-bit casts and extracts pass an undefined vector as their unused source: false warnings.
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
#pragma GCC diagnostic ignored "-Wuninitialized"
#endif
/**
 * splitRow with AVX-512: the compares as masks, labels and flags built in bytes from them, counts per lane in
 * vector registers, summed once per row (not reduced per block as splitRow's byte counters are). The same bits as
 * splitRow: labels are 0, l1, l1 + l2 or kInvalid in any width, and the rest are compares and selects.
 */
template <typename T, bool kRescue>
KP_TARGET_AVX512 RowCounts splitRow512(const T* src, int w, const ValueSplit& s, std::uint8_t* lab, T* dst,
                                       const T* in, std::uint8_t* cand)
{
  constexpr bool k8 = sizeof(T) == 1;
  constexpr int L = 64 / sizeof(T);
  using Mask = std::conditional_t<k8, __mmask64, __mmask32>;
  using Tr = DepthTraits<T>;
  constexpr T none = Tr::kNoReturn;
  const bool rescuable = s.t1 < none && (s.l1 == kFloor || s.l1 == kAboveCeiling);
  const auto splat = [](int x) KP_TARGET_AVX512 {
    return k8 ? _mm512_set1_epi8(static_cast<char>(x)) : _mm512_set1_epi16(static_cast<short>(x));
  };
  const __m512i t1 = splat(s.t1), t2 = splat(s.t2), vnone = splat(none), rt1 = splat(rescuable ? s.t1 : none);
  const __m512i minvalid = splat(Tr::kMinValid), move1 = splat(s.min_move - 1);
  // Counts per lane (a masked subtraction of -1 adds one, in the mask registers: moving masks to general registers
  // for popcounts costs more on some CPUs), summed per row and every 255 blocks (8-bit lanes).
  const __m512i minus1 = _mm512_set1_epi32(-1);
  __m512i c1 = _mm512_setzero_si512(), c2 = c1, ci = c1, cc = c1;
  int n1 = 0, n2 = 0, ni = 0, nc = 0;
  const auto count = [&](__m512i& c, Mask m) KP_TARGET_AVX512 {
    c = k8 ? _mm512_mask_sub_epi8(c, m, c, minus1) : _mm512_mask_sub_epi16(c, m, c, minus1);
  };
  const auto flush = [&]() KP_TARGET_AVX512 {
    for (__m512i* c : {&c1, &c2, &ci, &cc})
    {
      const __m512i sum = k8 ? _mm512_sad_epu8(*c, _mm512_setzero_si512())  // 8 sums of 8 lanes
                             : _mm512_madd_epi16(*c, _mm512_set1_epi16(1));  // 16 sums of 2 lanes
      const int n = k8 ? static_cast<int>(_mm512_reduce_add_epi64(sum)) : _mm512_reduce_add_epi32(sum);
      (c == &c1 ? n1 : c == &c2 ? n2 : c == &ci ? ni : nc) += n;
      *c = _mm512_setzero_si512();
    }
  };
  // Where kept and below-floor pixels first and last appear: the first column, and the last block's mask.
  int kept_first = -1, below_first = -1, kept_at = -1, below_at = -1;
  std::uint64_t kept_mask = 0, below_mask = 0;
  const auto track = [](Mask m, int u, int& first, int& at, std::uint64_t& last) {
    if (m == 0)
      return;
    if (first < 0)
      first = u + __builtin_ctzll(m);
    at = u;
    last = m;
  };
  // One block of L pixels from u (live: the lanes inside the row; counted: those not counted yet).
  const auto block = [&](int u, Mask live, Mask counted) KP_TARGET_AVX512 {
    __m512i v, raw = _mm512_setzero_si512();
    Mask g1, g2, inv, unknown = 0, above = 0, inband = 0;
    if constexpr (k8)
    {
      v = _mm512_maskz_loadu_epi8(live, src + u);
      g1 = _mm512_cmpge_epu8_mask(v, t1);
      g2 = _mm512_cmpge_epu8_mask(v, t2);
      inv = _mm512_cmpeq_epi8_mask(v, vnone);
      _mm512_mask_storeu_epi8(dst + u, live, _mm512_mask_mov_epi8(v, g1, vnone));  // removed: 255
      if constexpr (kRescue)
      {
        raw = _mm512_maskz_loadu_epi8(live, in + u);
        unknown = _mm512_cmplt_epu8_mask(raw, minvalid);
        raw = _mm512_mask_mov_epi8(raw, unknown, vnone);  // DepthTraits::map
        above = _mm512_cmpgt_epu8_mask(raw, _mm512_adds_epu8(v, move1));  // raw - v >= min_move
        inband = _mm512_cmpge_epu8_mask(raw, rt1) & _mm512_cmplt_epu8_mask(raw, t2);
      }
    }
    else
    {
      v = _mm512_maskz_loadu_epi16(live, src + u);
      g1 = _mm512_cmpge_epu16_mask(v, t1);
      g2 = _mm512_cmpge_epu16_mask(v, t2);
      inv = _mm512_cmpeq_epi16_mask(v, vnone);
      _mm512_mask_storeu_epi16(dst + u, live, _mm512_maskz_mov_epi16(static_cast<Mask>(~g1), v));  // removed: 0
      if constexpr (kRescue)
      {
        raw = _mm512_maskz_loadu_epi16(live, in + u);
        unknown = _mm512_cmplt_epu16_mask(raw, minvalid);
        raw = _mm512_mask_mov_epi16(raw, unknown, vnone);
        above = _mm512_cmpgt_epu16_mask(raw, _mm512_adds_epu16(v, move1));
        inband = _mm512_cmpge_epu16_mask(raw, rt1) & _mm512_cmplt_epu16_mask(raw, t2);
      }
    }
    // Labels in bytes: l1 from t1, + l2 from t2, no return kInvalid (it is >= t1 and >= t2).
    const __m512i l1 = _mm512_set1_epi8(static_cast<char>(s.l1)), l2 = _mm512_set1_epi8(static_cast<char>(s.l2));
    __m512i l = _mm512_maskz_mov_epi8(g1, l1);
    l = _mm512_mask_add_epi8(l, g2, l, l2);
    l = _mm512_mask_mov_epi8(l, inv, _mm512_set1_epi8(kInvalid));
    if constexpr (k8)
      _mm512_mask_storeu_epi8(lab + u, live, l);
    else
      _mm256_mask_storeu_epi8(lab + u, live, _mm512_castsi512_si256(l));
    count(c1, g1 & counted);
    count(c2, g2 & counted);
    count(ci, inv & counted);
    track(static_cast<Mask>(~g1 & live), u, kept_first, kept_at, kept_mask);  // kept: below t1
    track(static_cast<Mask>(_mm512_cmpeq_epi8_mask(l, _mm512_set1_epi8(kBelowFloor)) & live), u, below_first, below_at,
          below_mask);
    if constexpr (kRescue)
    {
      const Mask kb = _mm512_cmpeq_epi8_mask(l, _mm512_set1_epi8(kKept)) |
                      _mm512_cmpeq_epi8_mask(l, _mm512_set1_epi8(kBelowFloor));
      const Mask f = kb & above & inband;
      const __m512i one = _mm512_maskz_mov_epi8(f, _mm512_set1_epi8(1));
      if constexpr (k8)
        _mm512_mask_storeu_epi8(cand + u, live, one);
      else
        _mm256_mask_storeu_epi8(cand + u, live, _mm512_castsi512_si256(one));
      count(cc, f & counted);
    }
  };
  const Mask all = static_cast<Mask>(~Mask{0});
  if (w < L)
  {
    const Mask live = static_cast<Mask>(all >> (L - w));
    block(0, live, live);
  }
  else
  {
    int u = 0, blocks = 0;
    for (; u + L <= w; u += L)
    {
      block(u, all, all);
      if (++blocks == 255)
      {
        flush();
        blocks = 0;
      }
    }
    if (u < w)
      block(w - L, all, static_cast<Mask>(all << (u - (w - L))));  // the lanes before u are counted already
  }
  flush();
  RowCounts c = splitCounts(s, w, n1, n2, ni, nc);
  c.kept_first = kept_first;
  c.kept_last = kept_at < 0 ? -1 : kept_at + 63 - __builtin_clzll(kept_mask);
  c.below_first = below_first;
  c.below_last = below_at < 0 ? -1 : below_at + 63 - __builtin_clzll(below_mask);
  return c;
}
#pragma GCC diagnostic pop
#endif

// splitRow, with AVX-512 where the CPU has it.
template <typename T>
RowCounts splitRowFast(const T* src, int w, const ValueSplit& s, std::uint8_t* lab, T* dst, const T* in,
                       std::uint8_t* cand)
{
#if defined(KP_AVX512_PATHS)
  if (detail::vectorPaths())
    return in ? splitRow512<T, true>(src, w, s, lab, dst, in, cand)
              : splitRow512<T, false>(src, w, s, lab, dst, nullptr, nullptr);
#endif
  return splitRow<T>(src, w, s, lab, dst, in, cand);
}

/**
 * REP 117 for a scan's ranges: NaN for the beams outside [cov_lo, cov_hi] (no pixel of the image looks that way at
 * this pose), -Inf below range_min, +Inf above range_max; NaN stays NaN. Selects, in whole vectors.
 */
KP_CLONES void rep117(float* __restrict ranges, int n, float cov_lo, float cov_hi, float range_min, float range_max)
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int b = 0; b < n; ++b)
  {
    const float r = ranges[b], fb = static_cast<float>(b);  // b < 2^24: b + 1 is exact either way
    const float clipped = r < range_min ? -kInf : (r > range_max ? kInf : r);
    ranges[b] = (fb + 1.0f <= cov_lo || fb > cov_hi) ? nan : clipped;
  }
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

// First and last column with the label l (the row has one): 64 labels at a time, then 8 (labelBits), then one.
KP_CLONES int firstLabelled(const std::uint8_t* __restrict lab, int w, std::uint8_t l)
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

KP_CLONES int lastLabelled(const std::uint8_t* __restrict lab, int w, std::uint8_t l)
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

// z[u] = opened depth of the pixel u labelled below floor, +Inf for the others, u in [u0, u1].
template <typename T>
KP_CLONES void belowFloorDepth(const T* __restrict src, const std::uint8_t* __restrict lab, int u0, int u1,
                               float scale, float* __restrict z)
{
  for (int u = u0; u <= u1; ++u)
    z[u] = lab[u] == kBelowFloor ? static_cast<float>(src[u]) * scale : kInf;
}

// z[u] = depth of the kept pixel u of the cleaned row, +Inf for removed ones, for u in [u0, u1].
template <typename T>
KP_CLONES void keptDepth(const T* __restrict dst, int u0, int u1, float scale, float* __restrict z)
{
  for (int u = u0; u <= u1; ++u)
    z[u] = keptMetres(dst[u], scale);
}

// z[u] = measured (raw) depth of the pixel u labelled kept, +Inf for the others and for no return, u in [u0, u1].
template <typename T>
KP_CLONES void keptRawDepth(const T* __restrict in, const std::uint8_t* __restrict lab, int u0, int u1, float scale,
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
KP_CLONES void squareSpan(float* __restrict range, int u0, int u1)
{
  for (int u = u0; u <= u1; ++u)
    range[u] *= range[u];
}

KP_CLONES void minInto(const float* __restrict z, int u0, int u1, float* __restrict m)
{
  for (int u = u0; u <= u1; ++u)
    m[u] = z[u] < m[u] ? z[u] : m[u];
}

/**
 * Bins one row's pixels by the bearing of their centres (fc[u]: fractional bin position of pixel u's centre), min
 * per bin: a bin holds exactly the pixels whose centres fall in it. Where neighbouring centres are more than one
 * bin apart, the bins between them go to the nearer centre (in bearing), so that the binning leaves no bin empty
 * that a surface covers. Pixels whose neighbour lies half a turn away (straddling the direction behind) are not
 * used to fill. With kCount, counts[k] also counts the finite ranges that went into bin k.
 */
// What binCentres does with a range v that goes into bin k (k may be a padding slot, -1 or beams).
struct MinInto  // the nearest range per bin
{
  float* bins;
  void operator()(int k, float v) const { bins[k] = v < bins[k] ? v : bins[k]; }
};
struct MinCountInto  // the nearest range per bin, and how many finite ranges went in
{
  float* bins;
  std::int32_t* counts;
  void operator()(int k, float v) const
  {
    bins[k] = v < bins[k] ? v : bins[k];
    counts[k] += v < kInf;
  }
};
struct BandSum  // sum [um] and number of the ranges no farther than limit[k] (exact integers: any order, any team)
{
  const float* limit;
  std::int64_t* sum;
  std::int32_t* n;
  void operator()(int k, float v) const
  {
    const bool in = v <= limit[k];
    sum[k] += static_cast<std::int64_t>(static_cast<double>(in ? v : 0.0f) * 1e6 + 0.5);
    n[k] += in;
  }
};

// flag[u] = whether the centres of pixels u and u + 1 lie more than a bin apart, u in [a, b); 0 from b to b + 7.
KP_CLONES void gapFlags(const std::int32_t* __restrict key, int a, int b, std::uint8_t* __restrict flag)
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

// key: the bins of the centres (ScanProjector::spanBins).
template <typename Acc>
void binCentres(const float* fc, const float* range, int a, int b, int beams, float half_turn_bins,
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

/**
 * The pixels lo[j]..hi[j] into bin first + j, for j < n (ScanProjector::spanPixels): the same bins as binCentres
 * fills from the centres' side.
 */
template <typename Acc>
void pullBins(const float* range, const std::int32_t* lo, const std::int32_t* hi, int n, int first, const Acc& acc)
{
  for (int j = 0; j < n; ++j)
    for (int u = lo[j]; u <= hi[j]; ++u)
      acc(first + j, range[u]);
}

}  // namespace

namespace
{
/** The projector's terms of the horizontal projection, for the coverage of a pose. */
struct ScanGeometry
{
  const float *xe, *bx, *by;
  float ax, ay, lo, inv;
};
}  // namespace

/** Per-thread buffers, sized once per image size / beam count: no allocation per frame. */
struct Pipeline::Scratch
{
  std::vector<float> row, tmp;   // one image row of the input's type (floats are the widest)
  std::vector<float> ring;       // the 3x3 opening: three eroded rows of the input's type, row j in slot j % 3
  std::array<int, 3> ring_rows{};  // the row each slot holds (-1: none this frame)
  std::vector<float> t;          // threshold of each pixel of the row [m]
  std::vector<float> z;          // depth of kept pixels of the row [m], +Inf for removed ones
  std::vector<float> range;      // beam range of each pixel of the row [m], +Inf for removed ones
  std::vector<float> colmin;     // column projection: nearest kept depth per column [m]
  std::vector<float> edges;      // bin positions of the row's pixel centres
  std::vector<float> bins;       // nearest range per beam seen by this thread (+ a slot either side)
  std::vector<std::int32_t> key;  // bin of each pixel centre of the row
  std::vector<std::uint8_t> gaps;  // flags: pixels of the row whose next neighbour's centre is more than a bin away
  std::vector<std::int32_t> lo, hi;     // the pixels of each bin of the row
  std::vector<float> cliff_bins;          // nearest below-floor range per beam seen by this thread (+ padding)
  std::vector<std::int32_t> cliff_count;  // below-floor pixels per beam seen by this thread (+ padding)
  std::vector<std::int64_t> band_sum;     // surface_band: ranges within the band per beam [um] (+ padding)
  std::vector<std::int32_t> band_n;       // surface_band: their number per beam (+ padding)
  std::vector<std::uint8_t> vlab, vdst;  // labels of the 256 values (8-bit rows by value)
  std::vector<std::uint8_t> cand;        // pixels of an 8-bit row the rescue may relabel
  float cov_lo = 0.0f, cov_hi = 0.0f;  // ScanProjector::coverage over this thread's rows
  std::array<std::uint64_t, kNumLabels> counts{};
};

Pipeline::Pipeline(const Camera& camera, const Config& config)
{
  camera.validate();
  config.validate();
  camera_ = camera;
  config_ = config;
  projector_.configure(camera_, config_);
  confidence_.configure(projector_.beams(), config_);
}

Pipeline::~Pipeline() = default;

void Pipeline::setConfig(const Config& config)
{
  config.validate();
  // The learned floor correction belongs to a mounting: a new static pose or refinement setting starts afresh.
  if (config.sensor_height != config_.sensor_height || config.sensor_pitch != config_.sensor_pitch ||
      config.sensor_roll != config_.sensor_roll || config.refine_floor != config_.refine_floor)
    floor_fit_.reset();
  config_ = config;
  projector_.configure(camera_, config_);
  confidence_.configure(projector_.beams(), config_);
  lut_valid_ = false;
  planes_ = PlaneModel();  // forces the terms to be recomputed
}

void Pipeline::setCamera(const Camera& camera)
{
  camera.validate();
  camera_ = camera;
  projector_.configure(camera_, config_);
  confidence_.configure(projector_.beams(), config_);
  planes_ = PlaneModel();
}

void Pipeline::reset()
{
  confidence_.reset();
  floor_fit_.reset();
}

void Pipeline::prepareBuffers(int threads)
{
  if (static_cast<int>(scratch_.size()) < threads)
    scratch_.resize(threads);
  const std::size_t w = camera_.width;
  const std::size_t beams = projector_.beams();
  for (int i = 0; i < threads; ++i)
  {
    if (!scratch_[i])
      scratch_[i] = std::make_unique<Scratch>();
    Scratch& s = *scratch_[i];
    s.row.resize(w);
    s.tmp.resize(w);
    s.ring.resize(3 * w);
    s.t.resize(w);
    s.z.resize(w);
    s.range.resize(w + 32);  // the pull's vector loads read up to 31 past a span's last pixel
    s.lo.resize(beams);
    s.hi.resize(beams);
    s.colmin.resize(w);
    s.edges.resize(w + 1);
    s.bins.resize(beams + 2);  // from beam -1 to beams: what lies outside the scan goes to the ends
    s.key.resize(w);
    s.gaps.resize(w + 8);
    s.cliff_bins.resize(beams + 2);
    s.cliff_count.resize(beams + 2);
    s.band_sum.resize(beams + 2);
    s.band_n.resize(beams + 2);
    s.vlab.resize(256);
    s.vdst.resize(256);
    s.cand.resize(w + 8);
  }
  spans_.resize(2 * static_cast<std::size_t>(camera_.height));
}

void Pipeline::process(const cv::Mat& depth, double base_pitch, double base_roll, FrameResult& out, double stamp)
{
  if (!std::isfinite(base_pitch) || !std::isfinite(base_roll))
  {
    std::ostringstream s;
    s << "pose: base_pitch = " << base_pitch << " rad, base_roll = " << base_roll << " rad: expected finite values";
    throw std::invalid_argument(s.str());
  }
  process(depth, SensorPose{config_.sensor_height, config_.sensor_pitch + base_pitch, config_.sensor_roll + base_roll},
          out, stamp);
}

void Pipeline::process(const cv::Mat& depth, const SensorPose& prior, FrameResult& out, double stamp)
{
  const auto t0 = Clock::now();
  if (depth.empty())
    throw std::invalid_argument("depth image is empty: expected a " + std::to_string(camera_.width) + "x" +
                                std::to_string(camera_.height) + " image");
  const int type = depth.type();
  if (depth.dims != 2 || (type != CV_8UC1 && type != CV_16UC1 && type != CV_32FC1))
    throw std::invalid_argument("depth image type " + cv::typeToString(type) + " with " +
                                std::to_string(depth.dims) + " dimensions: expected a 2-D 8UC1, 16UC1 or 32FC1 image");
  if (depth.cols != camera_.width || depth.rows != camera_.height)
  {
    std::ostringstream s;
    s << "depth image is " << depth.cols << "x" << depth.rows << " (width x height) but the camera model is "
      << camera_.width << "x" << camera_.height;
    throw std::invalid_argument(s.str());
  }
  const double pitch = prior.pitch, roll = prior.roll, height = prior.height;
  if (!std::isfinite(pitch) || !std::isfinite(roll) || std::fabs(pitch) > kHalfPi + 1e-9 ||
      std::fabs(roll) > kHalfPi + 1e-9)
  {
    std::ostringstream s;
    s << "pose: pitch = " << pitch << " rad, roll = " << roll
      << " rad (sensor + base): expected finite values with |pitch|, |roll| <= pi/2";
    throw std::invalid_argument(s.str());
  }
  if (!(std::isfinite(height) && height > 0.0 && height < config_.ceiling_height))
  {
    std::ostringstream s;
    s << "pose: height = " << height << " m: expected a sensor height > 0 and below ceiling_height = "
      << config_.ceiling_height << " m";
    throw std::invalid_argument(s.str());
  }

  const Encoding enc = type == CV_8UC1 ? Encoding::kMono8 : (type == CV_16UC1 ? Encoding::kMono16 : Encoding::kFloat32);
  if (!lut_valid_ || enc != lut_encoding_)
  {
    lut_.build(config_.threshold_curve, enc, config_.max_depth);
    lut_encoding_ = enc;
    if (enc == Encoding::kMono8)
      value_terms_ = valueTerms<std::uint8_t>(lut_.valueTable(), depthScale<std::uint8_t>(config_.max_depth));
    else if (enc == Encoding::kMono16)
      value_terms_ = valueTerms<std::uint16_t>(lut_.valueTable(), depthScale<std::uint16_t>(config_.max_depth));
    lut_valid_ = true;
  }
  const auto t_fit = Clock::now();
  out.pose = floor_fit_.refine(depth, camera_, config_, lut_, prior, stamp, out.floor_fit);
  out.times.floor_fit = msSince(t_fit);
  if (planes_.update(camera_, config_, out.pose.height, out.pose.pitch, out.pose.roll))
    projector_.setPose(out.pose.pitch, out.pose.roll);
  out.depth.create(depth.size(), type);
  out.labels.create(depth.size(), CV_8UC1);
  out.times.prepare = msSince(t0);

  switch (type)
  {
    case CV_8UC1:
      run<std::uint8_t>(depth, out);
      break;
    case CV_16UC1:
      run<std::uint16_t>(depth, out);
      break;
    default:
      run<float>(depth, out);
      break;
  }
  out.times.total = msSince(t0);
}

/**
 * surface_band > 0: each beam's range becomes the mean of its ranges no farther than surface_band * t(m) beyond its
 * nearest m (out.scan.ranges on entry). A second pass over the kept spans, binned exactly as the first, at the
 * measured depth of the kept pixels: the opening's max of mins is biased towards the sensor on noise (by about
 * one sigma), the raw depth is not. (Raw >= opened, so no raw range lies below m.)
 */
/**
 * In a parallel region: this thread's scratch; one thread also sets team to the number of threads OpenMP gave
 * (only their scratch holds this frame's sums).
 */
Pipeline::Scratch& Pipeline::teamScratch(int& team)
{
#ifdef _OPENMP
#pragma omp single nowait
  team = omp_get_num_threads();
#endif
  return *scratch_[threadId()];
}

/** Buffers of one thread for binSpan. */
struct Pipeline::SpanBuffers
{
  float *z, *fb, *range;
  std::int32_t* key;
  std::uint8_t* gaps;
  std::int32_t *lo, *hi;    // the pixels of each bin (ScanProjector::spanPixels)
};

namespace
{
/** The depths of a span that the caller put in SpanBuffers::z (+Inf where nothing is seen); bins get ranges. */
struct SpanDepths
{
  void depths(int, int, float*) const {}
  void ranges(const ScanProjector& p, int r, int a, int b, const float* z, float* range) const
  {
    p.spanRanges(r, a, b, z, range);
  }
  void squareRanges(float*, int, int) const {}
};

/**
 * The depths of the kept pixels of a cleaned row (+Inf for removed ones), read where they are needed; bins get
 * squared ranges (ScanProjector::spanKeptSquaredRanges), rooted once per beam when the threads' bins are merged.
 */
template <typename T>
struct KeptDepths
{
  const T* row;
  float scale;
  void depths(int a, int b, float* z) const { keptDepth<T>(row, a, b, scale, z); }
  void ranges(const ScanProjector& p, int r, int a, int b, const float*, float* range) const
  {
    p.spanKeptSquaredRanges<T>(r, a, b, row, scale, range);
  }
  void squareRanges(float* range, int a, int b) const { squareSpan(range, a, b); }
};
}  // namespace

/**
 * Bins the span a..b of row r, whose depths src gives (SpanDepths, KeptDepths), into acc. One pixel either side
 * goes in as +Inf too: a gap between the span's end and its neighbour is split between them.
 */
template <typename Acc, typename Src>
void Pipeline::binSpan(int r, int a, int b, const SpanBuffers& buf, const Src& src, const Acc& acc) const
{
  SpanPlan plan;
  const int n = projector_.spanPlan(r, a, b, plan);
  binSpan(r, a, b, n, plan, buf, src, acc);
}

/** binSpan with the span's plan and its ScanProjector::spanPlan result n already found. */
template <typename Acc, typename Src>
void Pipeline::binSpan(int r, int a, int b, int n, const SpanPlan& plan, const SpanBuffers& buf, const Src& src,
                       const Acc& acc) const
{
  if (n == 0)
    return;
  if (n > 0)
  {
    ScanProjector::planPixels(plan, buf.lo, buf.hi);
    src.ranges(projector_, r, a, b, buf.z, buf.range);
    if constexpr (std::is_same_v<Acc, MinInto>)
    {
      if (detail::pullNearest(buf.range, buf.lo, buf.hi, n, acc.bins + plan.first))
        return;
    }
    else if constexpr (std::is_same_v<Acc, MinCountInto>)
    {
      if (detail::pullNearest(buf.range, buf.lo, buf.hi, n, acc.bins + plan.first, acc.counts + plan.first))
        return;
    }
    pullBins(buf.range, buf.lo, buf.hi, n, plan.first, acc);
    return;
  }
  src.depths(a, b, buf.z);
  const int w = camera_.width;
  const int a1 = std::max(0, a - 1), b1 = std::min(w - 1, b + 1);
  for (int u = a1; u < a; ++u)
    buf.z[u] = kInf;
  for (int u = b + 1; u <= b1; ++u)
    buf.z[u] = kInf;
  projector_.spanBins(r, a1, b1, buf.z, buf.fb, buf.key, buf.range);
  src.squareRanges(buf.range, a1, b1);
  binCentres(buf.fb, buf.range, a1, b1, projector_.beams(), 3.14159265f / projector_.angleIncrement(), buf.key,
             buf.gaps, acc);
}

template <typename T>
void Pipeline::surfaceMeans(const cv::Mat& depth, FrameResult& out, int threads)
{
  const int h = camera_.height, beams = projector_.beams();
  std::vector<float>& ranges = out.scan.ranges;
  band_limit_.assign(beams + 2, -1.0f);  // padding slots: nothing is ever within
  for (int k = 0; k < beams; ++k)
  {
    const float m = ranges[k];
    if (m < kInf)
      band_limit_[k + 1] = static_cast<float>(m + config_.surface_band * evaluateCurve(config_.threshold_curve, m));
  }
  const float scale = depthScale<T>(config_.max_depth);
  int team = 1;
#pragma omp parallel num_threads(threads)
  {
    Scratch& s = teamScratch(team);
    std::fill(s.band_sum.begin(), s.band_sum.end(), 0);
    std::fill(s.band_n.begin(), s.band_n.end(), 0);
    const BandSum acc{band_limit_.data() + 1, s.band_sum.data() + 1, s.band_n.data() + 1};
    const SpanBuffers buf{s.z.data(), s.edges.data(), s.range.data(), s.key.data(), s.gaps.data(), s.lo.data(),
                          s.hi.data()};
#pragma omp for schedule(dynamic, 8)
    for (int r = 0; r < h; ++r)
    {
      const int a = spans_[2 * r], b = spans_[2 * r + 1];
      if (a > b)
        continue;
      keptRawDepth<T>(depth.ptr<T>(r), out.labels.ptr<std::uint8_t>(r), a, b, scale, buf.z);
      binSpan(r, a, b, buf, SpanDepths{}, acc);
    }
  }
  for (int k = 0; k < beams; ++k)
  {
    std::int64_t sum = 0;
    std::int64_t n = 0;
    for (int i = 0; i < team; ++i)
    {
      sum += scratch_[i]->band_sum[k + 1];
      n += scratch_[i]->band_n[k + 1];
    }
    if (n > 0)  // always, where the beam has a finite nearest range: that pixel is within the band
      ranges[k] = static_cast<float>(static_cast<double>(sum) / static_cast<double>(n) * 1e-6);
  }
}

template <typename T>
void Pipeline::run(const cv::Mat& depth, FrameResult& out)
{
  using Tr = DepthTraits<T>;
  const int threads = config_.num_threads > 0 ? config_.num_threads : defaultThreads();
  prepareBuffers(threads);
  const int h = depth.rows, w = depth.cols;
  const int ksize = config_.open_kernel_size;
  const int rad = ksize >= 3 ? ksize / 2 : 0;
  const bool rect = config_.open_kernel_shape == KernelShape::kRect;

  // Stage 1: unknown -> no return, then the opening's erosion (or the whole OpenCV opening for other shapes).
  // Stage 2, rows in parallel: dilation, plane removal, labels, cleaned depth, each row's kept span and its beam
  // binning into the thread's bins (the column projection: the thread's column minima, binned after the rows).
  // One parallel region for the rectangular opening's erosion and stage 2 (each fork costs a wake-up).
  auto t1 = Clock::now();
  // The 3x3 opening streams: each thread erodes the rows its rows' dilation needs, as it goes, into a ring of three
  // rows (two more per chunk of rows than a whole eroded image, but no pass and no wait between the two).
  const bool stream = rad == 1 && rect;
  if (rad > 0 && rect && !stream)
  {
    eroded_.create(depth.size(), depth.type());
  }
  else if (rad > 0 && !rect)
  {
    mapped_.create(depth.size(), depth.type());
#pragma omp parallel for num_threads(threads) schedule(static)
    for (int r = 0; r < h; ++r)
    {
      const T* in = depth.ptr<T>(r);
      T* m = mapped_.ptr<T>(r);
      for (int u = 0; u < w; ++u)
        m[u] = Tr::map(in[u]);
    }
    const int cv_shape = config_.open_kernel_shape == KernelShape::kCross ? cv::MORPH_CROSS : cv::MORPH_ELLIPSE;
    cv::morphologyEx(mapped_, opened_, cv::MORPH_OPEN, cv::getStructuringElement(cv_shape, cv::Size(ksize, ksize)));
  }
  const float scale = depthScale<T>(config_.max_depth), inv_scale = 1.0f / scale;
  const std::vector<float>& colterm = planes_.colTerm();
  const float* col = colterm.data();
  const float* rowterm = planes_.rowTerm().data();
  const float floor_h = planes_.floorOffset();
  const float ceil_h = planes_.ceilingOffset();
  const int beams = projector_.beams();
  const float half_turn_bins = 3.14159265f / projector_.angleIncrement();
  const ThresholdLut& lut = lut_;
  const bool column = projector_.projection() == Projection::kColumn;
  const bool cliff = config_.cliff_scan || config_.cliff_in_scan;
  // 8- and 16-bit frames without roll: classify each row by value thresholds (see ValueSplit).
  constexpr bool kIntegerDepth = std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::uint16_t>;
  bool by_value = false;
  std::array<float, 256> colc;
  std::array<std::uint8_t, 256> values;
  ValueProof proof;
  if constexpr (kIntegerDepth)
  {
    by_value = std::all_of(colterm.begin(), colterm.end(), [&](float c) { return c == colterm[0]; });
    colc.fill(colterm[0]);
    if constexpr (std::is_same_v<T, std::uint8_t>)
      for (int v = 0; v < 256; ++v)
        values[v] = static_cast<std::uint8_t>(v);
    proof.build(value_terms_, floor_h, ceil_h);
  }
  // The projector's row terms, for the coverage of this pose below.
  ScanGeometry geo{};
  if (!column)
  {
    const ScanProjector& p = projector_;
    geo.xe = p.xe_.data();
    geo.bx = p.bx_.data();
    geo.by = p.by_.data();
    geo.ax = p.ax_;
    geo.ay = p.ay_;
    geo.lo = p.lo_;
    geo.inv = 1.0f / p.inc_;
  }

  int team = 1;  // threads OpenMP actually gave: only their scratch holds this frame's bins
  Clock::time_point t2 = t1;
#pragma omp parallel num_threads(threads)
  {
    Scratch& s = teamScratch(team);
    s.ring_rows.fill(-1);
    if (rad > 0 && rect && !stream)
    {
#pragma omp for schedule(static)
      for (int r = 0; r < h; ++r)
        detail::erodeMappedRow<T>(depth, r, rad, reinterpret_cast<T*>(s.tmp.data()), eroded_.ptr<T>(r));
    }
#pragma omp single nowait
    t2 = Clock::now();
    std::fill(s.bins.begin(), s.bins.end(), kInf);
    if (cliff)
    {
      std::fill(s.cliff_bins.begin(), s.cliff_bins.end(), kInf);
      std::fill(s.cliff_count.begin(), s.cliff_count.end(), 0);
    }
    s.counts.fill(0);
    T* row = reinterpret_cast<T*>(s.row.data());
    T* tmp = reinterpret_cast<T*>(s.tmp.data());
    float* z = s.z.data();
    float* range = s.range.data();
    float* fb = s.edges.data();
    float* bins = s.bins.data() + 1;  // bins[-1] and bins[beams] take what lies outside the scan
    const SpanBuffers buf{z, fb, range, s.key.data(), s.gaps.data(), s.lo.data(), s.hi.data()};
    if (column)
      std::fill(s.colmin.begin(), s.colmin.end(), kInf);
    if (!column)
    {
      // ScanProjector::coverage, split over the threads: the bin positions of the outer edges of each row.
      s.cov_lo = kInf;
      s.cov_hi = -kInf;
#pragma omp for schedule(static) nowait
      for (int r = 0; r < h; ++r)
      {
        for (const float x : {geo.xe[0], geo.xe[w]})
        {
          const float f = rayBin(x, geo.ax, geo.ay, geo.bx[r], geo.by[r], geo.lo, geo.inv);
          s.cov_lo = std::min(s.cov_lo, f);
          s.cov_hi = std::max(s.cov_hi, f);
        }
      }
    }

    // Chunks dealt in turn (thread t takes chunks t, t + T, ...): neighbouring chunks cost about the same, so the
    // threads' shares even out without the shared counter of a dynamic schedule (by the bench, 2 threads gave
    // 1.4-1.8x one with a dynamic schedule on this 2-CPU machine, 1.70-1.79x dealt in turn).
#pragma omp for schedule(static, 1)
    for (int chunk = 0; chunk < (h + kRowChunk - 1) / kRowChunk; ++chunk)
    {
      const int r0 = chunk * kRowChunk, r1 = std::min(h, r0 + kRowChunk);
      for (int r = r0; r < r1; ++r)
      {
        const T* src;
        if (stream)
        {
          const T* e[3];  // eroded rows r - 1, r, r + 1 (the row itself at the image's edges)
          for (int d = 0; d < 3; ++d)
          {
            const int j = std::min(std::max(r + d - 1, 0), h - 1), slot = j % 3;
            T* ring = reinterpret_cast<T*>(s.ring.data()) + static_cast<std::size_t>(slot) * w;
            if (s.ring_rows[slot] != j)
            {
              detail::erodeMappedRow<T>(depth, j, 1, tmp, ring);
              s.ring_rows[slot] = j;
            }
            e[d] = ring;
          }
          detail::dilate3Rows<T>(e[0], e[1], e[2], w, row);
          src = row;
        }
        else if (rad > 0 && rect)
        {
          detail::rectRow<T, false>(eroded_, r, rad, tmp, row);
          src = row;
        }
        else if (rad > 0)
        {
          src = opened_.ptr<T>(r);
        }
        else
        {
          const T* in = depth.ptr<T>(r);
          for (int u = 0; u < w; ++u)
            row[u] = Tr::map(in[u]);
          src = row;
        }

        T* dst = out.depth.ptr<T>(r);
        std::uint8_t* lab = out.labels.ptr<std::uint8_t>(r);
        RowCounts c;
        bool done = false;
        if constexpr (kIntegerDepth)
        {
          if (by_value)
          {
            // Split over every value but no return, whichever the row holds: the thresholds of a search over the
            // row's own values would be these, clamped to them (the labels are monotone in the value), and the
            // rescue below looks at raw values, which may lie above the opened row's.
            const int lo = 0, hi = Tr::kNoReturn - 1;
            ValueSplit split;
            const ValueLabeler<T> label{values.data(), lut.valueTable(), colc.data(), rowterm[r], scale, floor_h, ceil_h};
            if (splitValues<T>(label, proof, lo, hi, s.vlab.data(), s.vdst.data(), split))
            {
              // The raw values the rescue may relabel are t1 and above; t(raw) >= t(t1) where the table does not
              // decrease.
              if (value_terms_.nondecreasing && split.t1 < Tr::kNoReturn)
                split.min_move = detail::rescueMove(lut.valueTable()[split.t1], inv_scale, Tr::kNoReturn);
              std::uint8_t* cand = s.cand.data();
              c = splitRowFast<T>(src, w, split, lab, dst, rad > 0 ? depth.ptr<T>(r) : nullptr, cand);
              if (c.candidates > 0)
              {
                const int kept = c.kept, below = w - c.kept - c.invalid - c.floor - c.ceiling;
                rescueCandidates(cand, depth.ptr<T>(r), src, lut, col, rowterm[r], scale, floor_h, ceil_h, w, lab,
                                 dst, c);
                // Relabelled pixels may have been the first or last of their label: look again.
                if (c.kept != kept)
                  c.kept_first = c.kept_last = -1;
                if (w - c.kept - c.invalid - c.floor - c.ceiling != below)
                  c.below_first = c.below_last = -1;
              }
              done = true;
            }
          }
        }
        if (!done)
        {
          thresholdRow<T>(src, lut, scale, w, s.t.data());
          if (rad > 0)
            c = classifyRow<T, true>(src, depth.ptr<T>(r), s.t.data(), col, rowterm[r], scale, floor_h, ceil_h, w, lab,
                                     dst, s.cand.data());
          else
            c = classifyRow<T, false>(src, nullptr, s.t.data(), col, rowterm[r], scale, floor_h, ceil_h, w, lab, dst,
                                      nullptr);
          if (c.candidates > 0)
            rescueCandidates<T>(s.cand.data(), depth.ptr<T>(r), src, lut, col, rowterm[r], scale, floor_h, ceil_h, w,
                                lab, dst, c);
        }

        s.counts[kKept] += c.kept;
        s.counts[kInvalid] += c.invalid;
        s.counts[kFloor] += c.floor;
        s.counts[kAboveCeiling] += c.ceiling;
        const int below = w - c.kept - c.invalid - c.floor - c.ceiling;
        s.counts[kBelowFloor] += below;
        if (cliff && below > 0)
        {
          // Negative obstacles: the row's below-floor pixels at their opened depth, binned like kept ones.
          const int a = c.below_first >= 0 ? c.below_first : firstLabelled(lab, w, kBelowFloor);
          const int b = c.below_last >= 0 ? c.below_last : lastLabelled(lab, w, kBelowFloor);
          belowFloorDepth<T>(src, lab, a, b, scale, z);
          binSpan(r, a, b, buf, SpanDepths{}, MinCountInto{s.cliff_bins.data() + 1, s.cliff_count.data() + 1});
        }
        spans_[2 * r] = w;
        spans_[2 * r + 1] = -1;
        if (c.kept == 0)
          continue;
        // Only the span from the first to the last kept pixel can reach a bin.
        const int a = c.kept_first >= 0 ? c.kept_first : firstLabelled(lab, w, kKept);
        const int b = c.kept_last >= 0 ? c.kept_last : lastLabelled(lab, w, kKept);
        spans_[2 * r] = a;
        spans_[2 * r + 1] = b;
        if (column)
        {
          // The column projection's bin and range factor depend on the column only: keep the nearest depth
          // per column and bin the columns once per frame.
          keptDepth<T>(dst, a, b, scale, z);
          minInto(z, a, b, s.colmin.data());
        }
      }
      if (column)
        continue;
      // The horizontal projection bins each row on its own, into this thread's bins: the chunk's rows' bins first
      // (each a chain of dependent operations from the span's ends, independent of the other rows': the CPU
      // overlaps them), then their pixels.
      std::array<SpanPlan, kRowChunk> plans;
      std::array<int, kRowChunk> n{};
      for (int r = r0; r < r1; ++r)
        if (spans_[2 * r] <= spans_[2 * r + 1])
          n[r - r0] = projector_.spanPlan(r, spans_[2 * r], spans_[2 * r + 1], plans[r - r0]);
      for (int r = r0; r < r1; ++r)
        if (spans_[2 * r] <= spans_[2 * r + 1])
          binSpan(r, spans_[2 * r], spans_[2 * r + 1], n[r - r0], plans[r - r0], buf,
                  KeptDepths<T>{out.depth.ptr<T>(r), scale}, MinInto{bins});
    }
    // (implicit barrier: the column projection's bins need every row's column minima)

    if (column)
    {
      // The column projection's bin and range depend on the column only: bin the columns' nearest depths once.
      projector_.spanBins(0, 0, w - 1, s.colmin.data(), fb, s.key.data(), range);
      binCentres(fb, range, 0, w - 1, beams, half_turn_bins, s.key.data(), s.gaps.data(), MinInto{bins});
    }
  }
  out.times.erode = std::chrono::duration<double, std::milli>(t2 - t1).count();
  out.times.classify_scan = msSince(t2);

  // Stage 3: reduce the threads' bins, apply REP 117, rolling confidence.
  t1 = Clock::now();
  ScanData& scan = out.scan;
  scan.angle_min = projector_.angleMin();
  scan.angle_max = projector_.angleMax();
  scan.angle_increment = projector_.angleIncrement();
  scan.range_min = static_cast<float>(config_.range_min);
  scan.range_max = static_cast<float>(config_.range_max);
  scan.ranges.assign(beams, kInf);
  out.counts.fill(0);
  for (int i = 0; i < team; ++i)
  {
    const Scratch& s = *scratch_[i];
    for (int b = 0; b < beams; ++b)
      scan.ranges[b] = std::min(scan.ranges[b], s.bins[b + 1]);
    for (int k = 0; k < kNumLabels; ++k)
      out.counts[k] += s.counts[k];
  }
  if (!column)  // the horizontal projection's bins hold squared ranges (KeptDepths)
    for (float& r : scan.ranges)
      r = std::sqrt(r);
  if (config_.surface_band > 0.0)
  {
    const auto ts = Clock::now();
    surfaceMeans<T>(depth, out, threads);
    const double ms = msSince(ts);
    out.times.classify_scan += ms;
    t1 += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double, std::milli>(ms));
  }
  float cov_lo, cov_hi;
  if (column)
  {
    projector_.coverage(cov_lo, cov_hi);
  }
  else
  {
    cov_lo = kInf;
    cov_hi = -kInf;
    for (int i = 0; i < team; ++i)
    {
      cov_lo = std::min(cov_lo, scratch_[i]->cov_lo);
      cov_hi = std::max(cov_hi, scratch_[i]->cov_hi);
    }
  }
  // Negative obstacles: beams with at least cliff_min_pixels below-floor pixels.
  ScanData& cl = out.cliff;
  cl.ranges.clear();
  cl.intensities.clear();
  if (cliff)
  {
    cl.ranges.assign(beams, kInf);
    cliff_count_.assign(beams, 0);
    for (int i = 0; i < team; ++i)
    {
      const Scratch& s = *scratch_[i];
      for (int b = 0; b < beams; ++b)
      {
        cl.ranges[b] = std::min(cl.ranges[b], s.cliff_bins[b + 1]);
        cliff_count_[b] += s.cliff_count[b + 1];
      }
    }
    for (int b = 0; b < beams; ++b)
    {
      if (cliff_count_[b] < config_.cliff_min_pixels)
        cl.ranges[b] = kInf;
      if (config_.cliff_in_scan)
        scan.ranges[b] = std::min(scan.ranges[b], cl.ranges[b]);
    }
    if (!config_.cliff_scan)
      cl.ranges.clear();
  }
  cl.angle_min = scan.angle_min;
  cl.angle_max = scan.angle_max;
  cl.angle_increment = scan.angle_increment;
  cl.range_min = scan.range_min;
  cl.range_max = scan.range_max;
  for (std::vector<float>* ranges : {&scan.ranges, &cl.ranges})
    rep117(ranges->data(), static_cast<int>(ranges->size()), cov_lo, cov_hi, scan.range_min, scan.range_max);
  confidence_.apply(scan.ranges, scan.intensities);
  out.times.confidence = msSince(t1);
}

}  // namespace kinect_pipeline
