// The standalone node: the same class as the nodelet, in its own process.
#include <cstring>
#include <iostream>

#include <ros/ros.h>

#include "kinect_pipeline/ros/kinect_pipeline_ros.h"

int main(int argc, char** argv)
{
  for (int i = 1; i < argc; ++i)
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0)
    {
      std::cout << kinect_pipeline::usageText();
      return 0;
    }
  ros::init(argc, argv, "kinect_pipeline");
  ros::NodeHandle nh, pnh("~");
  try
  {
    kinect_pipeline::KinectPipelineRos node(nh, pnh, ros::this_node::getName());
    ros::spin();
  }
  catch (const kinect_pipeline::StartupError& e)
  {
    ROS_FATAL("%s", e.what());
    return 1;
  }
  return 0;
}
