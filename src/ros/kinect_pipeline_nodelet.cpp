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
    // The manager logs an exception from here with its reason, but the loader process (what the user launched)
    // only says that loading failed: ~startup_error tells the launch file's loader (scripts/load_into_manager) why.
    ros::NodeHandle& pnh = getPrivateNodeHandle();
    pnh.deleteParam("startup_error");
    try
    {
      impl_ = std::make_unique<KinectPipelineRos>(getNodeHandle(), pnh, getName());
    }
    catch (const StartupError& e)
    {
      pnh.setParam("startup_error", std::string(e.what()));
      throw;
    }
  }
  std::unique_ptr<KinectPipelineRos> impl_;
};

}  // namespace kinect_pipeline

PLUGINLIB_EXPORT_CLASS(kinect_pipeline::KinectPipelineNodelet, nodelet::Nodelet)
