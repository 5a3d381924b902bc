/**
 * @file camera_info_pairing.h
 * @brief Depth images and their camera_info, paired by the node itself (image_transport's CameraSubscriber pairs by
 *        exact stamp only and says nothing useful when camera_info never comes).
 *
 * An image is paired with the camera_info of the same stamp when there is one. When the camera_info messages do not
 * change (the same K, D, size and frame as the one before: a driver's, or `rostopic pub -r 5`), an image is paired
 * with the latest one whatever its stamp ("by recency"), as the content is the same; while images have been finding
 * the camera_info of their stamp, an image newer than the latest camera_info waits for its own first. Otherwise the
 * image waits (a few at most) for the camera_info of its stamp. ROS-free in time: no ros::Time::now(), so it is testable alone.
 */
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <vector>

#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/CompressedImage.h>
#include <sensor_msgs/Image.h>
#include <std_msgs/Header.h>

namespace kinect_pipeline
{

/** One input frame, raw or compressed, kept whole while its fate is open. */
struct DepthInput
{
  std_msgs::Header header;
  sensor_msgs::CameraInfoConstPtr info;             // null until paired
  sensor_msgs::ImageConstPtr image;                 // raw (or an image_transport plugin's decoded image)
  sensor_msgs::CompressedImageConstPtr compressed;  // compressedDepth or compressed, decoded by the node
};

/** How an image found its camera_info. */
enum class InfoMatch
{
  kExactStamp,  ///< the camera_info of the image's stamp
  kLatest,      ///< the latest camera_info, which had not changed (its stamp differs)
};

class CameraInfoPairing
{
public:
  /** @param max_waiting images that wait for a camera_info at most; the oldest is given up beyond. */
  explicit CameraInfoPairing(std::size_t max_waiting = 5) : max_waiting_(max_waiting) {}

  struct Outcome
  {
    std::vector<DepthInput> paired;     ///< in arrival order, each with its info
    std::vector<DepthInput> given_up;   ///< waited too long (no camera_info for them), oldest first
  };

  /** An image arrives. */
  Outcome image(DepthInput in);
  /** A camera_info arrives: the images waiting for it are paired. */
  Outcome info(const sensor_msgs::CameraInfoConstPtr& info);

  /** camera_info messages received so far. */
  std::uint64_t infos() const { return infos_; }
  /** Images paired so far, per InfoMatch. */
  std::uint64_t paired(InfoMatch m) const { return m == InfoMatch::kExactStamp ? exact_ : latest_count_; }
  /** camera_info messages that differed from the one before (K, D, size or frame). */
  std::uint64_t changes() const { return changes_; }
  /** Images waiting now. */
  std::size_t waiting() const { return waiting_.size(); }
  /** The latest camera_info (null before the first). */
  const sensor_msgs::CameraInfoConstPtr& latest() const { return latest_; }

  /** @return true if @p a and @p b describe the same camera: K, D, distortion model, size, binning, ROI, frame. */
  static bool sameCamera(const sensor_msgs::CameraInfo& a, const sensor_msgs::CameraInfo& b);

private:
  /** @return the camera_info of @p stamp, or null. */
  sensor_msgs::CameraInfoConstPtr withStamp(const ros::Time& stamp) const;
  /** Pairs @p in if it can be now: @return false if it must wait. */
  bool tryPair(DepthInput& in, Outcome& out);

  std::size_t max_waiting_;
  std::deque<sensor_msgs::CameraInfoConstPtr> recent_;  // the last few, for exact stamps
  sensor_msgs::CameraInfoConstPtr latest_;
  bool steady_ = false;       // the latest camera_info is the same camera as the one before it (or is the first)
  bool expect_exact_ = false;  // the last image paired found the camera_info of its stamp
  std::deque<DepthInput> waiting_;
  std::uint64_t infos_ = 0, exact_ = 0, latest_count_ = 0, changes_ = 0;
};

}  // namespace kinect_pipeline
