/**
 * @file conversions.h
 * @brief The one boundary between ROS messages and the core's types (no math lives in callbacks).
 */
#pragma once

#include <string>

#include <geometry_msgs/Quaternion.h>
#include <geometry_msgs/Transform.h>
#include <opencv2/core.hpp>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/LaserScan.h>
#include <std_msgs/Header.h>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/pose.h"
#include "kinect_pipeline/pipeline.h"

namespace kinect_pipeline
{
namespace conversions
{

/**
 * @brief Camera model of the images a CameraInfo goes with: its K (fx = K[0], fy = K[4], cx = K[2], cy = K[5],
 *        rectified depth) taken down to its ROI and binning (REP 104), by cameraFromIntrinsics (io/depth_image.h).
 * @throw std::invalid_argument for what cameraFromIntrinsics refuses, quoting the values.
 */
Camera cameraFromInfo(const sensor_msgs::CameraInfo& info);
/**
 * @brief The camera of a rectified image the CameraInfo goes with: P's (rectifiedIntrinsics, io/depth_image.h) where
 *        P is set, as image_geometry takes it, else K's; its ROI and binning applied as cameraFromInfo does.
 */
Camera rectifiedCameraFromInfo(const sensor_msgs::CameraInfo& info);

/**
 * @brief A cv::Mat over a depth image's data, without a copy where the byte order is the host's.
 * @param buffer where a byte-swapped copy is kept when the image's byte order differs from the host's
 * @return CV_8UC1 for "8UC1"/"mono8" (normalised with max_depth), CV_16UC1 for "16UC1"/"mono16" (mm),
 *         CV_32FC1 for "32FC1" (m)
 * @throw std::invalid_argument for another encoding, empty data, a step smaller than width * pixel size or
 *        data shorter than step * height, quoting the values.
 */
cv::Mat depthFromImage(const sensor_msgs::Image& image, cv::Mat& buffer);

/**
 * @brief The depth image of a sensor_msgs/CompressedImage: compressed_depth_image_transport's compressedDepth
 *        ("16UC1; compressedDepth png", RVL, 32FC1; see the core's compressed_depth.h), or compressed_image_transport's
 *        PNG of 16-bit depth ("16UC1; png compressed", "mono16; png compressed": a bare 16-bit PNG).
 * @param expected the size camera_info gives (empty: any)
 * @throw std::invalid_argument naming the format and what is supported (8-bit, JPEG or colour formats are no depth
 *        this node reads), or the payload's problem
 */
cv::Mat depthFromCompressed(const sensor_msgs::CompressedImage& image, cv::Size expected);

/** @return true for the encodings depthFromImage() reads. */
bool isSupportedEncoding(const std::string& encoding);

/**
 * @brief The sensor's pose relative to the floor from the transform of its optical frame in a gravity-aligned
 *        base frame (REP 103 optical: x right, y down, z forward); see the core's poseFromOpticalTransform().
 * @param base_frame_height height of the base frame's origin above the floor [m]
 * @param[out] yaw heading of the sensor in the base frame [rad], counter-clockwise
 * @return total height [m], pitch (+ looks down) and roll (+ right side down) [rad]
 */
SensorPose poseFromOpticalTransform(const geometry_msgs::Transform& base_to_optical, double base_frame_height,
                                    double& yaw);

/** @return the core's transform of a transform message. */
RigidTransform fromMsg(const geometry_msgs::Transform& t);

/** @brief Pitch (+ nose down) and roll (+ right side down) of an orientation quaternion (REP 103 body). */
void pitchRollFromQuaternion(const geometry_msgs::Quaternion& q, double& pitch, double& roll);

/** @brief Fills a LaserScan (REP 117 ranges, REP 103 angles) from the core's scan. */
void toLaserScan(const ScanData& scan, const std_msgs::Header& header, const std::string& frame_id,
                 double scan_time, sensor_msgs::LaserScan& out);

/** @brief Copies a cleaned depth image into an Image message with the given encoding and header. */
void toImage(const cv::Mat& depth, const std_msgs::Header& header, const std::string& encoding,
             sensor_msgs::Image& out);

/** @brief An rgb8 Image of the labels over the depth (thesis fig 4.17a colours, see colourLabels()). */
void toDebugImage(const cv::Mat& depth, const cv::Mat& labels, double max_depth, const std_msgs::Header& header,
                  sensor_msgs::Image& out);

}  // namespace conversions
}  // namespace kinect_pipeline
