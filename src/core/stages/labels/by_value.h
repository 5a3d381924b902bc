// Private to the core: the labelling of an 8- or 16-bit row without roll by value thresholds, the proof that the row's
// labels are monotone in the value (whose terms are computed from the rule, stages/labels/rule.h), and the labelling
// stage that takes it where the proof holds and labels pixel by pixel elsewhere (stages/labels/per_pixel.h). Design
// notes: docs/core_design.md ("Labels by value").
#pragma once

#include <array>
#include <cstdint>

#include "kinect_pipeline/model/encoding.h"
#include "stages/labels/per_pixel.h"
#include "stages/labels/rule.h"

namespace kinect_pipeline
{
namespace detail
{
/**
 * The threshold table's terms of the proof (ValueProof in stages/labels/by_value.cpp) that the labels of a row without
 * roll are monotone in the pixel value, over the values below the encoding's no-return value, with d = fl(v scale)
 * as the pixels get it and the bands of PlaneRule.
 */
struct ValueTerms
{
  bool nondecreasing = false;  ///< the table never decreases
  double gap_min = 0.0;        ///< smallest growth of d - farBand(t) from one value to the next [m]
  /// smallest growth of d - farBand(t) from a value to any value kValueWindow or more above it [m]
  double gap_window = 0.0;
  static constexpr int kValueWindow = 4;
  double d_max = 0.0, t_max = 0.0;  ///< depth and farBand(threshold) of the largest value [m]
};

/** The terms of a value table (ThresholdLut::valueTable) of the encoding T (8- or 16-bit) at scale [m per unit]. */
template <typename T>
ValueTerms valueTerms(const float* table, float scale);

/**
 * The fewest values an 8- or 16-bit pixel's raw value must lie above its opened value for the rescue to relabel it,
 * when the move bands (PlaneRule::moveBand) of the raw values it may relabel are t or more: pixels nearer than that
 * are not looked at. The rescue needs fl(fl(raw s) - fl(v s)) > moveBand(t(raw)) >= t, and raw - v <= k - 1 gives at
 * most (k - 1 + 4 u no_return) s on the left (u = 2^-24: three roundings of values up to no_return); the float
 * product t / s, a few roundings off, is taken 1e-6 smaller (relative).
 * @param t [m], @param inv_scale values per metre (1 / s), @param no_return the encoding's no-return value
 */
inline int rescueMove(float t, float inv_scale, int no_return)
{
  const float steps = t * inv_scale * (1.0f - 1e-6f) - (4.0f * static_cast<float>(no_return) / 16777216.0f + 1e-4f);
  return steps >= 1.0f ? static_cast<int>(steps) + 1 : 1;  // steps >= 1: the conversion is its floor
}

/**
 * Whether the labels of a row with rise R are monotone in the value (built per frame from the table's terms and
 * the planes' offsets): kYes, kWindowed (monotone but for a few values around each change, which are checked one
 * by one) or kNo. The argument is in stages/labels/by_value.cpp.
 */
enum class Monotone
{
  kNo,
  kYes,
  kWindowed,
};

struct ValueProof
{
  bool ok = false;  ///< table non-decreasing, ceil_h >= 0, floor_h > 0
  ValueTerms table;
  double floor_h = 0.0;

  void build(const ValueTerms& terms, float floor_h_, float ceil_h);
  Monotone monotone(float rise) const;
};

/** Scratch of one thread for the labelling of a row. */
struct LabelBuffers
{
  float* t;             ///< w: the row's thresholds (pixel by pixel)
  float* fh;            ///< w: the row's floor offsets (pixel by pixel, with a floor profile)
  std::int32_t* steps;  ///< w: the floor profile's lift step of each pixel
  std::uint8_t* cand;   ///< w + 8: the rescue's flags
  std::uint8_t *vlab, *vdst;  ///< 256 each: the labels of the 8-bit values (rows by value)
};

/**
 * The labels of 8- or 16-bit rows by value thresholds, for frames whose rows have one rise each (no roll): two
 * integer compares per pixel where the proof holds, and the rescue.
 */
template <typename T>
class ValueLabeller
{
public:
  /** @param vector the SIMD row kernel (false: its plain reference loop, the same bits) */
  ValueLabeller(const RuleTerms& f, const ValueTerms& terms, bool vector);
  /** @return false (nothing written) where the row's labels are not (provably) monotone in the value. */
  bool label(int r, const T* src, const T* in, int w, std::uint8_t* lab, T* dst, const LabelBuffers& buf,
             RowCounts& c) const;

private:
  RuleTerms f_;
  ValueTerms terms_;
  ValueProof proof_;
  std::array<float, 256> colc_;          ///< copies of the column term (all equal)
  std::array<std::uint8_t, 256> values_;  ///< 0, 1, ..., 255: the 8-bit values, labelled as a row
  bool vector_;
};

/**
 * Stage 2's labels of a row: by value where the frame has no roll, the encoding is 8- or 16-bit, the proof holds
 * and paths.labels is off; else pixel by pixel (the reference labeller).
 */
template <typename T>
class RowLabeller
{
  static constexpr bool kInteger = std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::uint16_t>;

public:
  /** @param paths labels: every row pixel by pixel (the reference path); portable: the plain row split */
  RowLabeller(const RuleTerms& f, const ValueTerms& terms, const ReferencePaths& paths)
      : f_(f), value_(f, terms, !paths.portable), by_value_(kInteger && !paths.labels && f.one_rise_per_row)
  {
  }
  /** @param in the raw row (nullptr: nothing was opened, no rescue) */
  RowCounts label(int r, const T* src, const T* in, int w, std::uint8_t* lab, T* dst, const LabelBuffers& buf) const
  {
    RowCounts c;
    if constexpr (kInteger)
      if (by_value_ && value_.label(r, src, in, w, lab, dst, buf, c))
        return c;
    return labelRowByPixel<T>(f_, r, src, in, w, lab, dst, buf.t, buf.fh, buf.steps, buf.cand);
  }

private:
  struct None
  {
    None(const RuleTerms&, const ValueTerms&, bool) {}
    bool label(int, const T*, const T*, int, std::uint8_t*, T*, const LabelBuffers&, RowCounts&) const { return false; }
  };
  RuleTerms f_;
  std::conditional_t<kInteger, ValueLabeller<T>, None> value_;
  bool by_value_;
};
}  // namespace detail
}  // namespace kinect_pipeline
