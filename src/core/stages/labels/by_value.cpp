// The labels of 8- and 16-bit rows without roll by value thresholds (stages/labels/by_value.h): the proof that a row's
// labels are monotone in the value, the search for the thresholds, the plain row kernel (the SIMD one's reference) and the
// rescue's flags. Design notes: docs/core_design.md ("Labels by value").
#include "stages/labels/by_value.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <type_traits>
#include <vector>

#include "stages/labels/split_row.h"

namespace kinect_pipeline
{
namespace detail
{
template <typename T>
ValueTerms valueTerms(const float* table, float scale)
{
  constexpr int last = DepthTraits<T>::kNoReturn - 1;
  constexpr int window = ValueTerms::kValueWindow;
  ValueTerms t;
  t.nondecreasing = true;
  std::vector<double> g(last + 1);  // d - farBand(t) of each value
  for (int v = 0; v <= last; ++v)
  {
    g[v] = static_cast<double>(static_cast<float>(v) * scale) - PlaneRule::farBand(table[v]);
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
  t.t_max = PlaneRule::farBand(table[last]);
  return t;
}
template ValueTerms valueTerms<std::uint8_t>(const float*, float);
template ValueTerms valueTerms<std::uint16_t>(const float*, float);

/*
 * When the labels of a row's values are provably monotone in the value, so that value thresholds found by a search
 * give every value's label. With rise R (the same for the whole row), d = fl(v scale), t = table[v] and the bands of
 * PlaneRule (non-decreasing in t):
 * - above ceiling, fl(d R) > ceil_h: fl(d R) is monotone in v, so is the test.
 * - floor or below (R < 0), fl(fl(d R) + floor_h) < -fl(nearBand(t) R): the left side does not grow with v, the
 *   right side does not shrink (t does not decrease), so once true it stays true.
 * - below (R < 0), fl(fl(d R) + floor_h) < fl(farBand(t) R): differs from G = floor_h + (d - farBand(t)) R by at
 *   most eta = PlaneRule::belowTestError; if d - farBand(t) grows by at least gap_min from one value to the next,
 *   G falls by gap_min |R| and the test is monotone when gap_min |R| >= 2 eta; and it is never true when
 *   floor_h - d_max |R| > eta.
 * A 16-bit table in 1 cm cells steps up at each cell border, by more than a value's 1 mm where t(d) grows by more
 * than 1 mm per cm (the default curve beyond 6 m): d - t then dips by a little at each border. It still grows by
 * gap_window from any value to every value kValueWindow above it, so when gap_window |R| >= 2 eta the test
 * can only change more than once within kValueWindow values of where the search found it changing (windowed):
 * the values there are labelled one by one, and if any disagrees the row is labelled as when not monotone.
 */
void ValueProof::build(const ValueTerms& terms, float floor_h_, float ceil_h)
{
  table = terms;
  ok = terms.nondecreasing && ceil_h >= 0.0f && floor_h_ > 0.0f;
  floor_h = floor_h_;
}

Monotone ValueProof::monotone(float rise) const
{
  if (!ok)
    return Monotone::kNo;
  if (!(rise < 0.0f))
    return Monotone::kYes;  // kept, then above ceiling
  const double r = -static_cast<double>(rise);
  const double eta = PlaneRule::belowTestError(table.d_max * r, floor_h, table.t_max * r);
  if (table.gap_min * r >= 2.0 * eta || floor_h - table.d_max * r > eta)
    return Monotone::kYes;
  return table.gap_window * r >= 2.0 * eta ? Monotone::kWindowed : Monotone::kNo;
}

namespace
{
/** Labels single values of a row by the rule, as classifyRow labels pixels: the same labels, bit for bit. */
template <typename T>
struct ValueRule
{
  const std::uint8_t* values;  // 8-bit: 0, 1, ..., 255 (labelled all at once when not monotone); 16-bit: unused
  const float *table, *colc;   // the threshold of each value (ThresholdLut::valueTable); 256 copies of the column term
  float rise_row;
  PlaneRule rule;  // the row's: its floor offset lifted by the profile, no lift table (ValueLabeller::label)

  std::uint8_t operator()(int v) const
  {
    float d;
    bool keep, below;
    return rule.label(static_cast<T>(v), table[v], colc[0] + rise_row, rule.floor_h, d, keep, below);
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
 * thresholds): the floor band starts where d + nearBand(t(d)) reaches the depth D = floor_h / -R at which the row's
 * rays meet the floor and ends where d - farBand(t(d)) does (t taken at the first guess); the ceiling plane is at
 * ceil_h / R.
 */
template <typename T>
void predictSplit(const ValueRule<T>& label, int lo, int hi, int& g1, int& g2)
{
  // A guess: float arithmetic and one division (the row loop waits for it).
  const PlaneRule& rule = label.rule;
  const float rise = label.colc[0] + label.rise_row, inv_scale = 1.0f / rule.scale;
  const auto value = [&](float x) { return !(x >= lo) ? lo : (x > hi ? hi : static_cast<int>(x)); };  // NaN: lo
  if (rise < 0.0f)
  {
    const float floor_at = rule.floor_h / (-rise * rule.scale);  // [values]
    const float t = label.table[value(floor_at)] * inv_scale;
    g1 = value(floor_at - PlaneRule::nearBand(label.table[value(floor_at - t)]) * inv_scale);
    g2 = value(floor_at + PlaneRule::farBand(label.table[value(floor_at + t)]) * inv_scale);
  }
  else
  {
    g1 = rise > 0.0f ? value(rule.ceil_h / (rise * rule.scale)) : hi;
    g2 = hi;
  }
}

/**
 * Monotone::kWindowed: where the below-floor test changes (t2, or t1 if the first removed value is below the floor;
 * hi + 1 if it never does), whether each value of the window either side has the label the split gives it.
 */
template <typename T>
bool windowAgrees(const ValueRule<T>& label, const ValueSplit& split, int hi)
{
  int c;
  if (split.l1 == kBelowFloor)
    c = split.t1;
  else if (split.l1 == kFloor)
    c = std::min(split.t2, hi + 1);
  else
    return true;  // kept, then above ceiling
  const int w = ValueTerms::kValueWindow;
  for (int v = std::max(split.t1, c - w); v <= std::min(hi, c + w - 1); ++v)
  {
    const int expect = v < split.t2 ? split.l1 : split.l1 + split.l2;
    if (label(v) != expect)
      return false;
  }
  return true;
}

// The thresholds of a row searched from where the planes predict them, when its labels are monotone (or
// windowed and the windows agree). @return false if they are not.
template <typename T>
bool searchSplit(const ValueRule<T>& label, Monotone monotone, int lo, int hi, ValueSplit& out)
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
  return monotone == Monotone::kYes || windowAgrees(label, out, hi);
}

// The thresholds of the 8-bit values lo..hi from every value's label (labelled as one row). @return false if the
// labels are not monotone.
bool scanSplit(const ValueRule<std::uint8_t>& label, int lo, int hi, std::uint8_t* lab, std::uint8_t* dst,
               ValueSplit& out)
{
  const int n = hi - lo + 1;
  classifyRow<std::uint8_t, false, false>(label.values + lo, nullptr, label.table + lo, nullptr, label.colc,
                                          label.rise_row, label.rule, n, lab, dst, nullptr);
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

/**
 * The value thresholds of a row with values lo..hi (< no-return), searched from where the planes predict them if
 * the labels are provably monotone, else (8-bit) from every value's label. @return false if they are not monotone
 * at all, or (16-bit) not provably so.
 */
template <typename T>
bool splitValues(const ValueRule<T>& label, const ValueProof& proof, int lo, int hi, std::uint8_t* lab,
                 std::uint8_t* dst, ValueSplit& out)
{
  const ValueSplit none{DepthTraits<T>::kNoReturn, DepthTraits<T>::kNoReturn, 0, 0};
  out = none;
  if (lo > hi)
    return true;
  const Monotone monotone = proof.monotone(label.colc[0] + label.rise_row);  // the row's whole rise
  if (monotone != Monotone::kNo)
  {
    if (searchSplit(label, monotone, lo, hi, out))
      return true;
    out = none;
  }
  if constexpr (std::is_same_v<T, std::uint8_t>)
    return scanSplit(label, lo, hi, lab, dst, out);
  else
    return false;  // 65535 values: the row is labelled pixel by pixel
}

// Labels, cleaned depth and counts of an 8- or 16-bit row from its value thresholds. Integer arithmetic of the
// pixel's width only, with counters of that width per block of 128 pixels (a multiple of every vector width), so
// that it vectorises without a scalar tail. With in (the raw row), also flags in cand the pixels the rescue may
// relabel: kept or below floor, moved nearer by the opening, and whose raw value has the label floor or above
// ceiling (values rt1 <= v < rt2).
template <typename T>
RowCounts splitRow(const T* __restrict src, int w, const ValueSplit& s, std::uint8_t* __restrict lab,
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

// splitRow, with the SIMD kernel where vector is on.
template <typename T>
void splitRowFast(const T* src, int w, const ValueSplit& s, std::uint8_t* lab, T* dst, const T* in, std::uint8_t* cand,
                  bool vector, RowCounts& c)
{
  if (!(vector && splitRowSimd<T>(src, w, s, lab, dst, in, cand, c)))
    c = splitRow<T>(src, w, s, lab, dst, in, cand);
}
}  // namespace

template <typename T>
ValueLabeller<T>::ValueLabeller(const RuleTerms& f, const ValueTerms& terms, bool vector)
    : f_(f), terms_(terms), vector_(vector)
{
  colc_.fill(f.col[0]);
  for (int v = 0; v < 256; ++v)
    values_[v] = static_cast<std::uint8_t>(v);
  proof_.build(terms, f.rule.floor_h, f.rule.ceil_h);
}

template <typename T>
bool ValueLabeller<T>::label(int r, const T* src, const T* in, int w, std::uint8_t* lab, T* dst,
                             const LabelBuffers& buf, RowCounts& c) const
{
  using Tr = DepthTraits<T>;
  // Split over every value but no return, whichever the row holds: the thresholds of a search over the row's own
  // values would be these, clamped to them (the labels are monotone in the value), and the rescue looks at raw
  // values, which may lie above the opened row's.
  const float* table = f_.lut->valueTable();
  // With a floor profile the row's one rise has one floor offset: the row's rule and proof take it.
  PlaneRule row_rule = f_.rule;
  ValueProof lifted;
  const ValueProof* proof = &proof_;
  if (f_.rule.lift.table)
  {
    row_rule.floor_h = f_.rule.floorAt(colc_[0] + f_.row[r]);
    row_rule.lift = {};
    lifted.build(terms_, row_rule.floor_h, row_rule.ceil_h);
    proof = &lifted;
  }
  const ValueRule<T> rule{values_.data(), table, colc_.data(), f_.row[r], row_rule};
  ValueSplit split;
  if (!splitValues<T>(rule, *proof, 0, Tr::kNoReturn - 1, buf.vlab, buf.vdst, split))
    return false;
  // The raw values the rescue may relabel are t1 and above; moveBand(t(raw)) >= moveBand(t(t1)) where the table
  // does not decrease.
  if (terms_.nondecreasing && split.t1 < Tr::kNoReturn)
    split.min_move = rescueMove(PlaneRule::moveBand(table[split.t1]), 1.0f / f_.rule.scale, Tr::kNoReturn);
  splitRowFast<T>(src, w, split, lab, dst, in, buf.cand, vector_, c);
  if (c.candidates > 0)
  {
    const int kept = c.kept, below = c.below(w);
    rescueRow(f_, r, buf.cand, in, src, w, lab, dst, c);
    // Relabelled pixels may have been the first or last of their label: look again.
    if (c.kept != kept)
      c.kept_first = c.kept_last = -1;
    if (c.below(w) != below)
      c.below_first = c.below_last = -1;
  }
  return true;
}

template class ValueLabeller<std::uint8_t>;
template class ValueLabeller<std::uint16_t>;
}  // namespace detail
}  // namespace kinect_pipeline
