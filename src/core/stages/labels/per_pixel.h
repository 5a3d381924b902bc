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
 * @param t scratch of w floats (the row's thresholds), @param cand scratch of w + 8 bytes (the rescue's flags)
 */
template <typename T>
RowCounts labelRowByPixel(const RuleTerms& f, int r, const T* src, const T* in, int w, std::uint8_t* lab, T* dst,
                          float* t, std::uint8_t* cand);

/**
 * The labels of a row's pixels by the rule (PlaneRule::label), each with its threshold t[u] and rise col[u] +
 * rise_row, and (kRescue) in cand the flags of the pixels the rescue may relabel: kept or below the floor, with a
 * raw value in[u] (unmapped) that the opening moved nearer by more than moveBand(t[u]), a superset of those it
 * relabels (t(raw) >= t(opened): the table is non-decreasing). Without kRescue, in and cand are not used. kLift: the
 * floor offset of each pixel is rule.floorAt(its rise) (a floor profile); else rule.floor_h.
 */
template <typename T, bool kRescue, bool kLift>
RowCounts classifyRow(const T* src, const T* in, const float* t, const float* col, float rise_row, PlaneRule rule,
                      int w, std::uint8_t* lab, T* dst, std::uint8_t* cand);

/**
 * The rescue (PlaneRule::rescued) of the pixels of row r flagged in cand, a superset of those it relabels; updates
 * labels, cleaned depth and the counts c. @param in the raw row (unmapped), @param src the opened row
 */
template <typename T>
void rescueRow(const RuleTerms& f, int r, const std::uint8_t* cand, const T* in, const T* src, int w,
               std::uint8_t* lab, T* dst, RowCounts& c);
}  // namespace detail
}  // namespace kinect_pipeline
