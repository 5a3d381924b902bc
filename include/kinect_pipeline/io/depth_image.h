/**
 * @file depth_image.h
 * @brief Depth images and camera intrinsics as messages carry them (sensor_msgs/Image and CameraInfo fields),
 *        read into the core's types without any ROS type: the ROS layer (ros/conversions.h) and the Python tools
 *        (which read bags with rosbags) share these checks and messages.
 */
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"

namespace kinect_pipeline
{

/** The fields of a sensor_msgs/Image, by reference (data is not copied). */
struct ImageBuffer
{
  std::string encoding;        ///< e.g. "16UC1"
  std::uint32_t width = 0;     ///< [px]
  std::uint32_t height = 0;    ///< [px]
  std::uint32_t step = 0;      ///< bytes per row
  bool is_bigendian = false;   ///< byte order of multi-byte pixels
  const std::uint8_t* data = nullptr;
  std::size_t size = 0;        ///< bytes at data
};

/** @return true for the depth encodings depthFromBuffer() reads: 8UC1, mono8, 16UC1, mono16, 32FC1. */
bool isSupportedDepthEncoding(const std::string& encoding);

/**
 * @brief A cv::Mat over a depth image's data, without a copy where the byte order is the host's.
 * @param buffer where a byte-swapped copy is kept when the image's byte order differs from the host's
 * @return CV_8UC1 for "8UC1"/"mono8" (normalised with max_depth), CV_16UC1 for "16UC1"/"mono16" (mm),
 *         CV_32FC1 for "32FC1" (m)
 * @throw std::invalid_argument for another encoding, empty data, a step smaller than width * pixel size or
 *        data shorter than step * height, quoting the values.
 */
cv::Mat depthFromBuffer(const ImageBuffer& image, cv::Mat& buffer);

/**
 * The part of the full-resolution image a CameraInfo's K describes that the image holds (REP 104): its region of
 * interest, subsampled by binning_x and binning_y. image_proc's crop_decimate, for one, sends its images this way,
 * with the camera_info's width, height and K left at full resolution.
 */
struct ImageWindow
{
  std::uint32_t binning_x = 0, binning_y = 0;  ///< 0 and 1: every pixel
  std::uint32_t x_offset = 0, y_offset = 0;    ///< the ROI's first column and row [full-resolution px]
  std::uint32_t width = 0, height = 0;         ///< the ROI's size [full-resolution px]; all four 0: the whole image
};

/**
 * @brief Camera model from a CameraInfo's size, K (row-major 3x3) and window: fx = K[0], fy = K[4], cx = K[2],
 *        cy = K[5] (rectified depth) at full resolution; with a binning b or an ROI, the image's own camera has
 *        fx / b, (cx - x_offset) / b and the size ROI / b (rounded down), as image_geometry's PinholeCameraModel.
 * @param frame_id the camera_info's frame, quoted in the message for K[0] = 0
 * @throw std::invalid_argument for K[0] = 0 (an uncalibrated camera), a zero size, non-finite values, a K not of
 *        the form [fx s cx; 0 fy cy; 0 0 1], a skew s that would move a pixel by a pixel or more (the camera has
 *        no skew), or an ROI outside the image or with one side 0 but not all four, quoting them.
 */
Camera cameraFromIntrinsics(std::uint32_t width, std::uint32_t height, const std::array<double, 9>& K,
                            const std::string& frame_id, const ImageWindow& window = {});

/**
 * @brief The intrinsics of a rectified image from a CameraInfo's P (its left 3x3), as image_geometry takes them: a
 *        rectified image's camera is P's, which may differ from K (camera_calibration's P, with which image_proc
 *        rectifies; a stereo camera's rectified projection).
 * @return P's [fx 0 cx; 0 fy cy; 0 0 1] as a K, or nothing where P is not set (P[0] = 0) or not of that form
 */
std::optional<std::array<double, 9>> rectifiedIntrinsics(const std::array<double, 12>& P);

/** @return true where the host stores multi-byte values most significant byte first. */
bool hostIsBigEndian();

}  // namespace kinect_pipeline
