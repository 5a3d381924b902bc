// Private to the core: the labelling of a row by its value thresholds (stages/labels/by_value.cpp), its SIMD
// kernel (stages/labels/split_row.cpp, compiled once per target) and what the two share. Design notes:
// docs/core_design.md ("Labels by value"; "SIMD kernels and their references").
#pragma once

#include <cstdint>

#include "stages/labels/rule.h"

namespace kinect_pipeline
{
namespace detail
{
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
 * A row's labels (lab), cleaned depth (dst) and counts from its value thresholds, with the SIMD kernel of the
 * target the dispatch picks; with in (the raw row), also the rescue's flags (cand). The same bits and counts as
 * by_value.cpp's splitRow, its plain reference, which also gives the first and last kept and below-floor column.
 * @return false (nothing done) for rows narrower than one vector
 */
template <typename T>
bool splitRowSimd(const T* src, int w, const ValueSplit& s, std::uint8_t* lab, T* dst, const T* in,
                  std::uint8_t* cand, RowCounts& c);

/** A row's counts from those of its values at or above t1 (n1) and t2 (n2), of no return (ni) and flagged (nc). */
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
}  // namespace detail
}  // namespace kinect_pipeline
