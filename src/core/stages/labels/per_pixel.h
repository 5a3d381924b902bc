// Private to the core: the reference labeller, the plane removal rule (stages/labels/rule.h) applied pixel by pixel,
// and the rescue. Every row can be labelled this way; the value labelling (stages/labels/by_value.h) must give the same
// bits. Design notes: docs/core_design.md ("The rule", "Stage 2: labels").
#pragma once

#include <cstdint>

#include "stages/labels/rule.h"

namespace kinect_pipeline
{
namespace detail
{
/**
 * Plane removal of one row of opened values src: labels, cleaned depth (removed: DepthTraits::removed()) and the
 * rescue, with the raw row in (nullptr: nothing was opened, no rescue).
 * @param t, fh scratch of w floats each (the row's thresholds and floor offsets), @param steps scratch of w ints (the
 *        floor profile's steps), @param cand scratch of w + 8 bytes (the rescue's flags)
 */
template <typename T>
RowCounts labelRowByPixel(const RuleTerms& f, int r, const T* src, const T* in, int w, std::uint8_t* lab, T* dst,
                          float* t, float* fh, std::int32_t* steps, std::uint8_t* cand);

/**
 * The threshold t[u] of each pixel of a row (thresholdOf): gather, by the CPU's gather instruction where the SIMD
 * target has one (8 float lanes or more), else (and !gather: the reference) the plain loop. The same bits.
 */
template <typename T>
void rowThresholds(const T* src, const ThresholdLut& lut, float scale, int w, float* t, bool gather);

/**
 * The labels of a row's pixels by the rule (PlaneRule::label), each with its threshold t[u] and rise col[u] +
 * rise_row, and (kRescue) in cand the flags of the pixels the rescue may relabel: kept or below the floor, with a
 * raw value in[u] (unmapped) that the opening moved nearer by more than moveBand(t[u]), a superset of those it
 * relabels (t(raw) >= t(opened): the table is non-decreasing). Without kRescue, in and cand are not used. kLift: the
 * floor offset of pixel u is fh[u] (rule.floorAt(its rise): a floor profile); else rule.floor_h (fh not used).
 */
template <typename T, bool kRescue, bool kLift>
RowCounts classifyRow(const T* src, const T* in, const float* t, const float* fh, const float* col, float rise_row,
                      PlaneRule rule, int w, std::uint8_t* lab, T* dst, std::uint8_t* cand);

/**
 * The floor offset of each pixel of row r under a floor profile, rule.floorAt(col[u] + rise_row): the lift table's
 * steps (vectorised), then a plain gather. @param steps scratch of w ints, @param fh the offsets (w floats)
 */
void liftRow(const float* col, float rise_row, const PlaneRule& rule, int w, std::int32_t* steps, float* fh);

/**
 * liftRow()'s offsets, the same bits, as runs of one lift step each, for a column term monotone in u
 * (PlaneModel::monotoneColumns()): then so are the steps (fl(col[u] + rise_row), its distance from the table's
 * lowest rise, the product by the steps per rise, the clamps and the conversion are each non-decreasing), and each
 * step's pixels are one run, whose end is found by bisection. A row of a small roll crosses one or two steps.
 * @return false (nothing written) where the row crosses 16 steps or more: liftRow() is faster there
 */
bool liftRowByRuns(const float* col, float rise_row, const PlaneRule& rule, int w, float* fh);

/**
 * liftRow()'s offsets, the same bits, for a column term monotone in u (as liftRowByRuns()) where the row reads fewer
 * lift steps than the SIMD target's vectors have float lanes (16 on AVX-512, 8 on AVX2): liftRow()'s steps, then
 * each pixel's offset by a lookup in one vector of the row's offsets (no gather). @param steps scratch of w ints
 * @return false (nothing written) elsewhere
 */
bool liftRowByLookup(const float* col, float rise_row, const PlaneRule& rule, int w, std::int32_t* steps, float* fh);

/**
 * The rescue (PlaneRule::rescued) of the pixels of row r flagged in cand, a superset of those it relabels; updates
 * labels, cleaned depth and the counts c. @param in the raw row (unmapped), @param src the opened row
 */
template <typename T>
void rescueRow(const RuleTerms& f, int r, const std::uint8_t* cand, const T* in, const T* src, int w,
               std::uint8_t* lab, T* dst, RowCounts& c);
}  // namespace detail
}  // namespace kinect_pipeline
