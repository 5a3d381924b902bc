/**
 * @file rectify.h
 * @brief A raw depth image to the rectified one the core's pinhole camera describes, by its camera_info's lens
 *        distortion (distortion_model and D, as sensor_msgs/CameraInfo carries them). kinect2_bridge's
 *        `sd/image_depth`, for one, is raw: a Kinect v2's lens moves its corners by about 30 px.
 */
#pragma once

#include <array>
#include <optional>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"

namespace kinect_pipeline
{

/** Takes raw depth images of one camera to rectified ones of the same camera matrix (R = identity, P = K). */
class DepthRectifier
{
public:
  /**
   * @param camera the image's camera (fx, fy, cx, cy of its K; its binning and roi applied)
   * @param model "plumb_bob" (D: k1 k2 p1 p2 [k3]), "rational_polynomial" (k1 k2 p1 p2 k3 k4 k5 k6) or
   *        "equidistant" (k1 k2 k3 k4); any model, or none, with D all 0 is no distortion
   * @throw std::invalid_argument for another model with a D not all 0, a D of another length than the model's,
   *        or a value that is not finite, naming them
   */
  DepthRectifier(const Camera& camera, const std::string& model, const std::vector<double>& D);

  /** No distortion (D all 0): apply() copies. */
  bool identity() const { return identity_; }
  /** The farthest any pixel of the image moves [px]. */
  double maxShift() const { return max_shift_; }
  /** The fraction of the rectified image whose rays meet the raw image outside it (left as no measurement). */
  double outside() const { return outside_; }

  /**
   * The rectified image: each pixel takes the raw pixel nearest to where its ray meets the raw image (depth is
   * never blended across an edge), 0 (no measurement) where that lies outside it.
   * @param raw 8UC1, 16UC1 or 32FC1 of the camera's size
   * @throw std::invalid_argument for another size (naming both) or type
   */
  void apply(const cv::Mat& raw, cv::Mat& out) const;

private:
  int width_, height_;
  bool identity_ = true;
  double max_shift_ = 0.0, outside_ = 0.0;
  cv::Mat map_;  ///< CV_32SC1: the raw pixel v * width + u of each rectified one, -1 outside
};

/** A camera_info's lens: distortion_model, D, and R (row-major; all 0 where not set). */
struct CameraLens
{
  std::string model;
  std::vector<double> D;
  std::array<double, 9> R{};
  /**
   * R rotates the rays (set, and not the identity): a stereo camera's rectification. Depth from a stereo camera is
   * computed on rectified pairs, so its images are rectified whatever their topic's name.
   */
  bool stereo() const;
};

/**
 * @brief Whether the depth images on a topic are rectified before the pipeline, by a mode: "always" (when the
 *        camera_info has a distortion), "never", or "auto": as "always" unless the image topic's name says it is
 *        rectified already (its last name, before a transport's, holds "rect": image_rect, image_depth_rect,
 *        image_rect_raw), as ROS names its topics, or the camera is a stereo camera (CameraLens::stereo).
 * @param why set to what decided it, for messages
 * @throw std::invalid_argument for another mode, naming it
 */
bool rectifyWanted(const std::string& mode, const std::string& image_topic, const DepthRectifier& rectifier,
                   bool stereo, std::string& why);

/**
 * The rectification of one image topic's frames, as the node and the bag tools do it: rectifyWanted() decides it
 * anew, and a DepthRectifier is built, only where the mode, the camera or its distortion changed.
 */
class TopicRectification
{
public:
  /**
   * @return the image to process: @p depth itself, or its rectified image (held here until the next call)
   * @throw std::invalid_argument for a distortion it would need and cannot take, or a bad mode, naming them
   */
  const cv::Mat& apply(const std::string& mode, const std::string& image_topic, const Camera& camera,
                       const CameraLens& lens, const cv::Mat& depth);
  /** What decided the last frame's rectification (rectifyWanted's why); empty before the first. */
  const std::string& why() const { return why_; }
  /** Whether the last apply() decided anew (the first frame, or a change): for saying it once. */
  bool decidedAnew() const { return anew_; }
  /** Whether the last apply() rectified the image (else it is taken as rectified already). */
  bool rectifies() const { return wanted_; }
  /** Whether the last frame's camera has a lens distortion that the mode looked at (not with "never"). */
  bool distorts() const { return rectifier_ && !rectifier_->identity(); }

private:
  std::string mode_, topic_, why_;
  Camera camera_;
  CameraLens lens_;
  std::optional<DepthRectifier> rectifier_;
  bool wanted_ = false, anew_ = false;
  cv::Mat out_;
};

}  // namespace kinect_pipeline
