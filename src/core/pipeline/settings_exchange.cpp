#include "kinect_pipeline/settings_exchange.h"

#include <stdexcept>

namespace kinect_pipeline
{

void FramePipeline::process(const std::shared_ptr<const Config>& config, const Camera& camera, const cv::Mat& depth,
                            const SensorPose& pose, FrameResult& out, double stamp)
{
  if (!config)
    throw std::invalid_argument("FramePipeline::process: no config (null pointer)");
  if (!pipeline_)
  {
    pipeline_ = std::make_unique<Pipeline>(camera, *config);
    camera_ = camera;
    config_ = config;
    ++config_changes_;
  }
  else
  {
    if (config.get() != config_.get())
    {
      pipeline_->setConfig(*config);  // validates first: on error the old config stays in force
      config_ = config;
      ++config_changes_;
    }
    if (camera != camera_)
    {
      pipeline_->setCamera(camera);
      camera_ = camera;
    }
  }
  pipeline_->process(depth, pose, out, stamp);
}

void FramePipeline::reset()
{
  if (pipeline_)
    pipeline_->reset();
}

}  // namespace kinect_pipeline
