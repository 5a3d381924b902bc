/**
 * @file visualize.h
 * @brief Pictures of a processed frame (the ROS debug image and the Python report use the same one).
 */
#pragma once

#include <array>
#include <cstdint>

#include <opencv2/core.hpp>

namespace kinect_pipeline
{

/** RGB colour of each label (thesis fig 4.17a: floor green, ceiling blue); kept pixels are grey by depth. */
constexpr std::array<std::array<std::uint8_t, 3>, 5> kLabelColours = {{
    {0, 0, 0},       // kept: unused (grey by depth)
    {0, 0, 0},       // invalid: black
    {26, 191, 51},   // floor: green
    {38, 89, 242},   // above the ceiling plane: blue
    {230, 26, 153},  // below the floor: magenta
}};

/**
 * @brief Colours labels over depth: kept pixels grey (near = bright, @p max_depth = black), others in their
 *        label's colour.
 * @param depth CV_8UC1 (normalised with max_depth), CV_16UC1 (mm) or CV_32FC1 (m), any values
 * @param labels CV_8UC1 labels of the same size
 * @param max_depth [m], also the depth shown as black
 * @param rgb CV_8UC3 in RGB order (reused when the size matches)
 * @throw std::invalid_argument for other types or sizes.
 */
void colourLabels(const cv::Mat& depth, const cv::Mat& labels, double max_depth, cv::Mat& rgb);

}  // namespace kinect_pipeline
