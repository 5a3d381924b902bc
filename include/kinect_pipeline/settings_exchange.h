/**
 * @file settings_exchange.h
 * @brief Hands whole settings from a parameter thread to the frame thread, applied between frames.
 *
 * ROS-free: the node's dynamic_reconfigure callback posts validated settings from its thread; the image
 * callback takes the newest before each frame. A frame sees either the old settings or the new ones whole,
 * never half of a change; settings posted faster than frames arrive replace each other (the newest wins).
 */
#pragma once

#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <utility>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/pipeline.h"

namespace kinect_pipeline
{

/**
 * @brief A one-slot mailbox of immutable settings.
 *
 * post() from any thread; take() from the one thread that processes frames. The settings object is shared
 * read-only (std::shared_ptr<const T>): the frame thread keeps using the object it took while newer ones are
 * posted, and no thread ever writes to a posted object.
 */
template <class T>
class SettingsExchange
{
public:
  /** @brief Replaces what is pending (not yet taken) with @p settings. A null pointer is ignored. */
  void post(std::shared_ptr<const T> settings)
  {
    if (!settings)
      return;
    std::lock_guard<std::mutex> lock(mutex_);
    pending_ = std::move(settings);
    ++posted_;
  }

  /**
   * @brief Frame thread, between frames: makes the newest posted settings @p active.
   * @return true if @p active changed (the caller re-configures what depends on it), false if nothing was posted
   *         since the last take().
   */
  bool take(std::shared_ptr<const T>& active)
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (!pending_)
      return false;
    active = std::move(pending_);
    pending_.reset();
    return true;
  }

  /** @return how many settings were posted so far (for tests and diagnostics). */
  std::uint64_t posted() const
  {
    std::lock_guard<std::mutex> lock(mutex_);
    return posted_;
  }

private:
  mutable std::mutex mutex_;
  std::shared_ptr<const T> pending_;
  std::uint64_t posted_ = 0;
};

/**
 * @brief The frame thread's pipeline: made at the first frame, re-configured only when the settings object or
 *        the camera model changed since the last frame.
 *
 * Settings are told apart by identity: pass the std::shared_ptr taken from a SettingsExchange (or one aliasing a
 * member of it, e.g. `std::shared_ptr<const Config>(settings, &settings->core)`); the object is kept alive while
 * in use, so a new object never looks like the old one. Not thread-safe: one frame at a time, like Pipeline.
 */
class FramePipeline
{
public:
  /**
   * @brief Processes one frame at a pose given whole (Pipeline::process(depth, pose, out, stamp)).
   * @param stamp the frame's time [s] (the image's stamp), for the floor refinement's learned correction
   * @throw std::invalid_argument when the pipeline refuses the config, the camera, the image or the pose; the
   *        config and camera in force stay as they were, and the next frame tries again.
   */
  void process(const std::shared_ptr<const Config>& config, const Camera& camera, const cv::Mat& depth,
               const SensorPose& pose, FrameResult& out, double stamp = std::numeric_limits<double>::quiet_NaN());
  /** @brief Forgets the confidence history and the learned floor correction (no-op before the first frame). */
  void reset();
  /** @return the pipeline (null before the first frame), e.g. for its floorFit().learned(). */
  const Pipeline* pipeline() const { return pipeline_.get(); }
  /** @return the config in force (null before the first frame). */
  const std::shared_ptr<const Config>& config() const { return config_; }
  /** @return how many times the config was applied (the first frame included). */
  std::uint64_t configChanges() const { return config_changes_; }

private:
  std::unique_ptr<Pipeline> pipeline_;
  std::shared_ptr<const Config> config_;
  Camera camera_;
  std::uint64_t config_changes_ = 0;
};

}  // namespace kinect_pipeline
