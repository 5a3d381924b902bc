#include "kinect_pipeline/config.h"

#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "kinect_pipeline/sensor_model.h"
#include "kinect_pipeline/threshold_curve.h"

namespace kinect_pipeline
{
namespace
{
constexpr double kHalfPi = 1.57079632679489661923;

[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument(msg); }

void requireRange(const char* name, double v, double lo, double hi, const char* unit)
{
  if (!(std::isfinite(v) && v >= lo && v <= hi))
  {
    std::ostringstream s;
    s << "Config." << name << " = " << v << ": expected a value in [" << lo << ", " << hi << "] " << unit;
    fail(s.str());
  }
}

void requirePositive(const char* name, double v, const char* unit)
{
  if (!(std::isfinite(v) && v > 0.0))
  {
    std::ostringstream s;
    s << "Config." << name << " = " << v << ": expected a finite value > 0 " << unit;
    fail(s.str());
  }
}

std::string trim(const std::string& s)
{
  const auto b = s.find_first_not_of(" \t\n[]");
  if (b == std::string::npos)
    return "";
  const auto e = s.find_last_not_of(" \t\n[]");
  return s.substr(b, e - b + 1);
}
}  // namespace

std::vector<CurvePoint> defaultThresholdCurve()
{
  // The Kinect v2 preset's: 2 cm + 4.5 sigma (sigma = 1.5 mm + 1.9 mm * (z - 0.4)^2), rounded to millimetres.
  return sensorModel(kDefaultSensorModel).thresholdCurve();
}

std::vector<CurvePoint> parseThresholdCurve(const std::string& text)
{
  std::vector<CurvePoint> out;
  std::stringstream all(text);
  std::string item;
  while (std::getline(all, item, ','))
  {
    item = trim(item);
    if (item.empty())
      continue;
    const auto colon = item.find(':');
    if (colon == std::string::npos)
      fail("threshold_curve: '" + item + "' is not 'depth:threshold' (metres), e.g. '1.0:0.03, 4.0:0.14'");
    try
    {
      std::size_t used_d = 0, used_t = 0;
      const std::string ds = trim(item.substr(0, colon)), ts = trim(item.substr(colon + 1));
      const double d = std::stod(ds, &used_d);
      const double t = std::stod(ts, &used_t);
      if (used_d != ds.size() || used_t != ts.size())
        throw std::invalid_argument("trailing text");
      out.push_back({d, t});
    }
    catch (const std::logic_error&)
    {
      fail("threshold_curve: '" + item + "' is not 'depth:threshold' with two numbers in metres");
    }
  }
  validateThresholdCurve(out);
  return out;
}

std::string formatThresholdCurve(const std::vector<CurvePoint>& curve)
{
  std::ostringstream s;
  s << std::setprecision(6);
  for (std::size_t i = 0; i < curve.size(); ++i)
    s << (i ? ", " : "") << curve[i].depth << ":" << curve[i].threshold;
  return s.str();
}

Geometry geometryFromString(const std::string& s)
{
  if (s == "exact")
    return Geometry::kExact;
  if (s == "thesis")
    return Geometry::kThesis;
  fail("geometry = '" + s + "': expected 'exact' or 'thesis'");
}

Projection projectionFromString(const std::string& s)
{
  if (s == "horizontal")
    return Projection::kHorizontal;
  if (s == "column")
    return Projection::kColumn;
  fail("projection = '" + s + "': expected 'horizontal' or 'column'");
}

KernelShape kernelShapeFromString(const std::string& s)
{
  if (s == "rect")
    return KernelShape::kRect;
  if (s == "cross")
    return KernelShape::kCross;
  if (s == "ellipse")
    return KernelShape::kEllipse;
  fail("open_kernel_shape = '" + s + "': expected 'rect', 'cross' or 'ellipse'");
}

std::string toString(Geometry g) { return g == Geometry::kExact ? "exact" : "thesis"; }
std::string toString(Projection p) { return p == Projection::kHorizontal ? "horizontal" : "column"; }
std::string toString(KernelShape k)
{
  return k == KernelShape::kRect ? "rect" : (k == KernelShape::kCross ? "cross" : "ellipse");
}

void Config::validate() const
{
  requireRange("sensor_height", sensor_height, 0.01, 100.0, "m (height of the optical centre above the floor)");
  requireRange("sensor_pitch", sensor_pitch, -kHalfPi, kHalfPi, "rad (+ looks down)");
  requireRange("sensor_roll", sensor_roll, -kHalfPi, kHalfPi, "rad (+ right side down)");
  requirePositive("ceiling_height", ceiling_height, "m");
  if (!(ceiling_height > sensor_height))
  {
    std::ostringstream s;
    s << "Config.ceiling_height = " << ceiling_height << " m is not above Config.sensor_height = " << sensor_height
      << " m: the ceiling plane must be above the sensor";
    fail(s.str());
  }
  requireRange("max_depth", max_depth, 0.1, 1000.0, "m (depth of 8-bit value 255)");
  if (open_kernel_size < 0 || open_kernel_size > 31 || (open_kernel_size > 1 && open_kernel_size % 2 == 0))
  {
    std::ostringstream s;
    s << "Config.open_kernel_size = " << open_kernel_size << ": expected 0 or 1 (off) or an odd size 3..31 px";
    fail(s.str());
  }
  validateThresholdCurve(threshold_curve);
  requireRange("range_min", range_min, 0.0, 1000.0, "m");
  requireRange("range_max", range_max, 0.0, 1000.0, "m");
  if (!(range_max > range_min))
  {
    std::ostringstream s;
    s << "Config.range_max = " << range_max << " m must be greater than Config.range_min = " << range_min << " m";
    fail(s.str());
  }
  if (scan_beams < 0 || scan_beams > 100000)
  {
    std::ostringstream s;
    s << "Config.scan_beams = " << scan_beams << ": expected 0 (image width) or 1..100000 beams";
    fail(s.str());
  }
  requireRange("scan_fov", scan_fov, 0.0, 2.0 * 3.14159265358979323846, "rad (0 = the camera's)");
  requireRange("surface_band", surface_band, 0.0, 10.0, "(a multiple of the threshold curve t(d); 0 = nearest pixel)");
  if (cliff_min_pixels < 1 || cliff_min_pixels > 100000)
  {
    std::ostringstream s;
    s << "Config.cliff_min_pixels = " << cliff_min_pixels << ": expected 1..100000 pixels per beam";
    fail(s.str());
  }
  if (confidence_window < 1 || confidence_window > 1000)
  {
    std::ostringstream s;
    s << "Config.confidence_window = " << confidence_window << ": expected 1..1000 frames";
    fail(s.str());
  }
  requirePositive("confidence_distance", confidence_distance, "m");
  requireRange("min_intensity", min_intensity, 0.0, 1.0, "");
  requireRange("floor_max_height_error", floor_max_height_error, 0.001, 1.0, "m");
  requireRange("floor_max_pitch_error", floor_max_pitch_error, 0.0001, 0.5, "rad");
  requireRange("floor_max_roll_error", floor_max_roll_error, 0.0001, 0.5, "rad");
  if (floor_min_pixels < 1 || floor_min_pixels > 100000000)
  {
    std::ostringstream s;
    s << "Config.floor_min_pixels = " << floor_min_pixels << ": expected 1..100000000 image pixels";
    fail(s.str());
  }
  requireRange("floor_learn_time", floor_learn_time, 0.0, 3600.0, "s (0 = learn nothing)");
  if (num_threads < 0 || num_threads > 1024)
  {
    std::ostringstream s;
    s << "Config.num_threads = " << num_threads << ": expected 0 (OpenMP default) or 1..1024";
    fail(s.str());
  }
}

}  // namespace kinect_pipeline
