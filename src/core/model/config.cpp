// Config: the fields' table is model/config_table.cpp; the parameters are tabled in README.md, "Parameters".
#include "kinect_pipeline/model/config.h"

#include <cmath>
#include <iomanip>
#include <sstream>
#include <stdexcept>

#include "kinect_pipeline/model/config_table.h"
#include "kinect_pipeline/model/sensor_model.h"
#include "kinect_pipeline/model/threshold_curve.h"
#include "kinect_pipeline/types.h"

namespace kinect_pipeline
{
namespace
{
[[noreturn]] void fail(const std::string& msg) { throw std::invalid_argument(msg); }

/** Collects every problem of a config, so that one message can name them all. */
class Problems
{
public:
  explicit Problems(std::vector<std::string>& out) : out_(out) {}
  /** @return @p ok; records @p what (a stream of the message) when it is false. */
  bool check(bool ok, const std::ostringstream& what)
  {
    if (!ok)
      add(what.str());
    return ok;
  }
  void add(const std::string& msg) { out_.push_back(msg); }

private:
  std::vector<std::string>& out_;
};

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

std::vector<std::string> Config::problems() const
{
  std::vector<std::string> out;
  Problems p(out);
  // Each field on its own: the table's ranges (model/config_table.cpp).
  const std::vector<ConfigField>& fields = configFields();
  std::vector<bool> ok(fields.size());
  for (std::size_t i = 0; i < fields.size(); ++i)
  {
    const std::string problem = fields[i].rangeProblem(*this);
    ok[i] = problem.empty();
    if (!ok[i])
      p.add(problem);
  }
  const auto valid = [&](const char* name) { return ok[&configField(name) - fields.data()]; };
  if (valid("open_kernel_size"))
  {
    std::ostringstream s;
    s << "Config.open_kernel_size = " << open_kernel_size << ": expected 0 or 1 (off) or an odd size 3..31 px";
    p.check(!(open_kernel_size > 1 && open_kernel_size % 2 == 0), s);
  }
  try
  {
    validateThresholdCurve(threshold_curve);
  }
  catch (const std::invalid_argument& e)
  {
    p.add(e.what());
  }
  // Combinations, judged only when both fields are valid on their own.
  if (valid("ceiling_height") && valid("sensor_height"))
  {
    std::ostringstream s;
    s << "Config.ceiling_height = " << ceiling_height << " m is not above Config.sensor_height = " << sensor_height
      << " m: the ceiling plane must be above the sensor";
    p.check(ceiling_height > sensor_height, s);
  }
  if (valid("sensor_roll") && valid("geometry"))
    if (const std::string roll = rollProblem(sensor_roll, geometry, "Config.sensor_roll"); !roll.empty())
      p.add(roll);
  if (valid("range_min") && valid("range_max"))
  {
    std::ostringstream s;
    s << "Config.range_max = " << range_max << " m must be greater than Config.range_min = " << range_min << " m";
    p.check(range_max > range_min, s);
  }
  return out;
}

std::string rollProblem(double roll, Geometry geometry, const char* what)
{
  if (geometry != Geometry::kThesis || std::fabs(roll) <= kPi / 2)
    return "";
  std::ostringstream s;
  s << what << " = " << roll << " rad with geometry 'thesis': expected |roll| <= pi/2 (the thesis's planes are an "
    << "upright camera's); geometry 'exact' takes a camera upside down";
  return s.str();
}

void Config::validate() const
{
  const std::vector<std::string> all = problems();
  if (all.empty())
    return;
  std::string msg = all.front();
  for (std::size_t i = 1; i < all.size(); ++i)
    msg += "; " + all[i];
  fail(msg);
}

}  // namespace kinect_pipeline
