// Private to the core: stage 3, the frame's scan from the threads' bins: the nearest range per beam, the cliff scan,
// REP 117 and (Confidence, stages/scan.h) the rolling confidence. Design notes: docs/core_design.md ("Stage 3").
#pragma once

#include <cstdint>
#include <vector>

#include "kinect_pipeline/model/config.h"
#include "stages/scan/binning.h"

namespace kinect_pipeline
{
namespace detail
{
/** The nearest range of each of beams beams over the team's bins, rooted where the bins hold squared ranges. */
void mergeBins(const std::vector<const BinScratch*>& team, int beams, bool squared, std::vector<float>& ranges);

/**
 * Negative obstacles (Config::cliff_scan, cliff_in_scan): the nearest below-floor range of each beam over the team's
 * cliff bins where at least cliff_min_pixels fell in it, else +Inf, into cliff (left empty without cliff_scan); with
 * cliff_in_scan also into scan. @param count scratch
 */
void mergeCliff(const std::vector<const BinScratch*>& team, int beams, const Config& config,
                std::vector<std::int32_t>& count, std::vector<float>& scan, std::vector<float>& cliff);

/**
 * REP 117 for a scan's ranges: NaN for the beams outside [cov_lo, cov_hi] (no pixel of the image looks that way at
 * this pose), -Inf below range_min, +Inf above range_max; NaN stays NaN.
 */
void rep117(float* ranges, int n, float cov_lo, float cov_hi, float range_min, float range_max);
}  // namespace detail
}  // namespace kinect_pipeline
