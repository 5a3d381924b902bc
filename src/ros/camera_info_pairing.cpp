#include "kinect_pipeline/ros/camera_info_pairing.h"

#include <utility>

namespace kinect_pipeline
{
namespace
{
constexpr std::size_t kRecentInfos = 10;
}

bool CameraInfoPairing::sameCamera(const sensor_msgs::CameraInfo& a, const sensor_msgs::CameraInfo& b)
{
  return a.width == b.width && a.height == b.height && a.K == b.K && a.D == b.D &&
         a.distortion_model == b.distortion_model && a.binning_x == b.binning_x && a.binning_y == b.binning_y &&
         a.roi == b.roi && a.header.frame_id == b.header.frame_id;
}

sensor_msgs::CameraInfoConstPtr CameraInfoPairing::withStamp(const ros::Time& stamp) const
{
  for (auto it = recent_.rbegin(); it != recent_.rend(); ++it)
    if ((*it)->header.stamp == stamp)
      return *it;
  return nullptr;
}

bool CameraInfoPairing::tryPair(DepthInput& in, Outcome& out)
{
  if (sensor_msgs::CameraInfoConstPtr exact = withStamp(in.header.stamp))
  {
    in.info = exact;
    ++exact_;
    expect_exact_ = true;
  }
  else if (latest_ && steady_ && !(expect_exact_ && in.header.stamp > latest_->header.stamp))
  {
    // The same camera as before: the latest camera_info says what the image's own would.
    in.info = latest_;
    ++latest_count_;
    expect_exact_ = false;
  }
  else
  {
    return false;
  }
  out.paired.push_back(std::move(in));
  return true;
}

CameraInfoPairing::Outcome CameraInfoPairing::image(DepthInput in)
{
  Outcome out;
  if (!waiting_.empty() || !tryPair(in, out))
    waiting_.push_back(std::move(in));  // behind those waiting already: the order of the images is kept
  while (waiting_.size() > max_waiting_)
  {
    DepthInput oldest = std::move(waiting_.front());
    waiting_.pop_front();
    if (latest_ && steady_)
    {
      oldest.info = latest_;  // its own camera_info did not come in time; the camera has not changed
      ++latest_count_;
      out.paired.push_back(std::move(oldest));
    }
    else
    {
      out.given_up.push_back(std::move(oldest));
    }
  }
  // Those behind a paired one may pair now too.
  while (!waiting_.empty() && tryPair(waiting_.front(), out))
    waiting_.pop_front();
  return out;
}

CameraInfoPairing::Outcome CameraInfoPairing::info(const sensor_msgs::CameraInfoConstPtr& info)
{
  ++infos_;
  const bool changed = latest_ && !sameCamera(*latest_, *info);
  if (changed)
    ++changes_;
  steady_ = !changed;
  latest_ = info;
  recent_.push_back(info);
  if (recent_.size() > kRecentInfos)
    recent_.pop_front();
  Outcome out;
  while (!waiting_.empty() && tryPair(waiting_.front(), out))
    waiting_.pop_front();
  return out;
}

}  // namespace kinect_pipeline
