// Private to the core: a stereo camera's wrong matches taken as no return before the opening
// (Config::speckle_jump). Design notes: docs/core_design.md ("Wrong matches").
#pragma once

#include <opencv2/core.hpp>

namespace kinect_pipeline
{
namespace detail
{
/**
 * Copies @p depth (CV_8UC1, CV_16UC1 or CV_32FC1) into @p out, with each wrong match set to 0 (every encoding's
 * "no measurement"): a pixel nearer, by more than @p jump times its depth, than each of the four pixels two steps
 * away (left, right, above, below; one without a measurement counts as farther). An island of up to 2 x 2 pixels in
 * front of everything around it goes whole: the opening would keep it (it removes small far spots, not near ones),
 * and a stereo camera's wrong matches look so. Of a larger island only pixels with none of it two steps away go,
 * and the opening fills them again from their neighbours: a 3 x 3 island, or a line one pixel wide and three or
 * more long (a pole, an edge), stays. Pixels within two of the border stay.
 * @param out reused: no allocation once it has the image's size and type
 * @return the number of pixels set to 0
 */
int removeSpeckles(const cv::Mat& depth, double jump, cv::Mat& out, int threads);
}  // namespace detail
}  // namespace kinect_pipeline
