// Sensor presets and their noise models; sources and checks on real frames in docs/sensor_models.md.
#include "kinect_pipeline/model/sensor_model.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace kinect_pipeline
{
namespace
{
// The depths of the default curve's control points [m].
constexpr double kDepths[] = {0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0, 6.0, 8.0, 10.0, 12.0};
// The default cliff_min_pixels and the focal length it was chosen at (a Kinect v2) [px].
constexpr int kCliffPixels = 3;
constexpr double kCliffFx = 365.5;

std::vector<SensorModel> makeModels()
{
  std::vector<SensorModel> m;
  // Kinect v2 (time of flight): the curve the pipeline has always used, 2 cm + 4.5 sigma.
  m.push_back({"kinect_v2", "Microsoft Kinect v2 / Kinect for Xbox One (time of flight)",
               "sigma = 1.5 mm + 1.9 mm (z - 0.4 m)^2 (the thesis' model, of the form of Nguyen et al. 2012)",
               {0.0015, 0.0019, 0.4, 0.0, 4.5, 0.0, 0.02}, 10.0, Camera(512, 424, 365.5, 365.5, 255.5, 211.5),
               "kinect2_bridge (iai_kinect2)", "kinect2", "sd/image_depth",
               // t(z) rounded to millimetres, as it has always been (12 m: 1.1772 taken up to 1.178).
               {{0.5, 0.027}, {1.0, 0.030}, {1.5, 0.037}, {2.0, 0.049}, {2.5, 0.064}, {3.0, 0.085}, {3.5, 0.109},
                {4.0, 0.138}, {5.0, 0.208}, {6.0, 0.295}, {8.0, 0.521}, {10.0, 0.815}, {12.0, 1.178}},
               0.0});
  // Kinect v1 (structured light): random error 1.425 mm z^2 and a depth step of z^2 / (8 f b) (disparity in
  // 1/8 px, f = 580 px, b = 7.5 cm), both from Khoshelham & Elberink 2012; a floor pixel and the floor the pose
  // predicts each sit up to a step off. Rated range 0.8-4 m (Kinect for Windows, default mode).
  m.push_back({"kinect_v1", "Microsoft Kinect v1 / Kinect for Xbox 360, Asus Xtion (structured light)",
               "Khoshelham & Elberink 2012: sigma = 1.425 mm z^2, depth step z^2 / (8 f b) = 2.87 mm z^2",
               {0.0, 0.001425, 0.0, 1.0 / (8.0 * 580.0 * 0.075), 4.5, 2.0, 0.02}, 4.0,
               Camera(640, 480, 525.0, 525.0, 319.5, 239.5), "openni_launch / openni2_launch / freenect_launch",
               "camera", "depth/image_raw", {}, 0.0});
  // RealSense D4xx (active stereo): Intel's depth RMS error = z^2 * subpixel / (f * baseline), subpixel 0.08,
  // D435 baseline 50 mm, f 426 px at 848x480 (the subpixel step is in that RMS already: no step term).
  m.push_back({"realsense_d4xx", "Intel RealSense D415 / D435 / D455 (active stereo)",
               "Intel, Tuning depth cameras for best performance: RMS = z^2 * 0.08 / (f * b)",
               {0.0, 0.08 / (426.0 * 0.050), 0.0, 0.0, 4.5, 0.0, 0.02}, 6.0,
               Camera(848, 480, 426.0, 426.0, 424.0, 240.0), "realsense2_camera", "camera",
               // Wrong matches, islands in front of everything around them: taken as no measurement (docs/quality.md).
               "depth/image_rect_raw", {}, 0.125});
  // Azure Kinect (time of flight), NFOV unbinned: random error <= 17 mm (1 sigma) and systematic error
  // < 11 mm + 0.1 % of the distance over the mode's range (Microsoft's hardware specification, confirmed by
  // Tolgyessy et al. 2021); the noise of a time-of-flight pixel grows with the square of the distance
  // (returned power), so 17 mm at the end of the range (3.86 m) scaled by (z / 3.86)^2; the systematic part
  // goes into the margin (11 mm + 0.1 % of 3.86 m, taken at the end of the range).
  m.push_back({"azure_kinect", "Microsoft Azure Kinect DK (time of flight), NFOV unbinned",
               "Microsoft Azure Kinect DK hardware specification: random error <= 17 mm, systematic < 11 mm + 0.1 %",
               {0.001, 0.017 / (3.86 * 3.86), 0.0, 0.0, 4.5, 0.0, 0.02 + 0.011 + 0.001 * 3.86}, 3.86,
               Camera(640, 576, 504.0, 504.0, 320.0, 288.0), "Azure_Kinect_ROS_Driver", "",
               "depth/image_raw", {}, 0.0});
  // Orbbec Astra (structured light, like the Kinect v1): the same model with its focal length (570 px) and
  // baseline (7.5 cm); rated 0.6-8 m, reliable to about the Kinect v1's 4 m.
  m.push_back({"orbbec_astra", "Orbbec Astra / Astra Pro (structured light)",
               "as kinect_v1 (Khoshelham & Elberink 2012) with f = 570 px, b = 7.5 cm",
               {0.0, 0.001425, 0.0, 1.0 / (8.0 * 570.0 * 0.075), 4.5, 2.0, 0.02}, 4.0,
               Camera(640, 480, 570.0, 570.0, 319.5, 239.5), "astra_camera (ros_astra_camera) / openni2_launch",
               "camera", "depth/image_raw", {}, 0.0});
  return m;
}
}  // namespace

std::vector<CurvePoint> SensorModel::thresholdCurve() const
{
  if (!curve.empty())
    return curve;
  std::vector<CurvePoint> out;
  double last = 0.0;
  for (double z : kDepths)
  {
    last = std::max(last, std::round(noise.threshold(z) * 1000.0) / 1000.0);  // never decreasing
    out.push_back({z, last});
  }
  return out;
}

int SensorModel::cliffMinPixels() const
{
  const double scale = (camera.fx * camera.fy) / (kCliffFx * kCliffFx);
  return std::max(kCliffPixels, static_cast<int>(std::lround(kCliffPixels * scale)));
}

std::string SensorModel::depthTopic() const
{
  return (camera_ns.empty() ? "" : "/" + camera_ns) + "/" + image;
}

std::string SensorModel::infoTopic() const
{
  const std::string depth = depthTopic();
  return depth.substr(0, depth.rfind('/') + 1) + "camera_info";
}

const std::vector<SensorModel>& sensorModels()
{
  static const std::vector<SensorModel> models = makeModels();
  return models;
}

const SensorModel& sensorModel(const std::string& name)
{
  for (const SensorModel& m : sensorModels())
    if (m.name == name)
      return m;
  std::string names;
  for (const SensorModel& m : sensorModels())
    names += (names.empty() ? "" : ", ") + m.name;
  throw std::invalid_argument("sensor_model '" + name + "': expected one of " + names);
}

const std::vector<std::string>& sensorModelFields()
{
  static const std::vector<std::string> fields = {"threshold_curve", "range_max", "cliff_min_pixels", "speckle_jump"};
  return fields;
}

void applySensorModel(const std::string& name, Config& config, const std::vector<std::string>& keep)
{
  const SensorModel& m = sensorModel(name);
  const auto kept = [&](const char* f) { return std::find(keep.begin(), keep.end(), f) != keep.end(); };
  if (!kept("threshold_curve"))
    config.threshold_curve = m.thresholdCurve();
  if (!kept("range_max"))
    config.range_max = m.range_max;
  if (!kept("cliff_min_pixels"))
    config.cliff_min_pixels = m.cliffMinPixels();
  if (!kept("speckle_jump"))
    config.speckle_jump = m.speckle_jump;
}

}  // namespace kinect_pipeline
