// The nodelet: load kinect_pipeline/KinectPipelineNodelet into the camera driver's manager for zero-copy.
#include <memory>

#include <nodelet/nodelet.h>
#include <pluginlib/class_list_macros.hpp>

#include "kinect_pipeline/ros/kinect_pipeline_ros.h"

namespace kinect_pipeline
{

class KinectPipelineNodelet : public nodelet::Nodelet
{
private:
  void onInit() override
  {
    impl_ = std::make_unique<KinectPipelineRos>(getNodeHandle(), getPrivateNodeHandle(), getName());
  }
  std::unique_ptr<KinectPipelineRos> impl_;
};

}  // namespace kinect_pipeline

PLUGINLIB_EXPORT_CLASS(kinect_pipeline::KinectPipelineNodelet, nodelet::Nodelet)
