// The standalone node: the same class as the nodelet, in its own process.
#include <ros/ros.h>

#include "kinect_pipeline/ros/kinect_pipeline_ros.h"

int main(int argc, char** argv)
{
  ros::init(argc, argv, "kinect_pipeline");
  ros::NodeHandle nh, pnh("~");
  kinect_pipeline::KinectPipelineRos node(nh, pnh, ros::this_node::getName());
  ros::spin();
  return 0;
}
