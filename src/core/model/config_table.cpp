// The table of Config fields (model/config_table.h). The ranges are those of cfg/KinectPipeline.cfg, which
// test/python/test_ros_params.py compares with this table.
#include "kinect_pipeline/model/config_table.h"
#include "kinect_pipeline/types.h"

#include <cmath>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace kinect_pipeline
{
namespace
{
ConfigField row(const char* name, FieldKind kind, double lo, double hi, const char* unit, const char* doc)
{
  ConfigField f{};
  f.name = name;
  f.kind = kind;
  f.lo = lo;
  f.hi = hi;
  f.unit = unit;
  f.doc = doc;
  return f;
}

ConfigField real(const char* name, double Config::*m, double lo, double hi, const char* unit, const char* doc)
{
  ConfigField f = row(name, FieldKind::kReal, lo, hi, unit, doc);
  f.real = m;
  return f;
}

ConfigField integer(const char* name, int Config::*m, double lo, double hi, const char* unit, const char* doc)
{
  ConfigField f = row(name, FieldKind::kInteger, lo, hi, unit, doc);
  f.integer = m;
  return f;
}

ConfigField flag(const char* name, bool Config::*m, const char* doc)
{
  ConfigField f = row(name, FieldKind::kFlag, 0, 1, "-", doc);
  f.flag = m;
  return f;
}

ConfigField choice(const char* name, std::vector<std::string> names, const char* doc,
                   std::string (*of)(const Config&), void (*set)(Config&, const std::string&))
{
  ConfigField f = row(name, FieldKind::kChoice, 0, 0, "-", doc);
  f.choices = std::move(names);
  f.choice_of = of;
  f.set_choice = set;
  return f;
}

std::vector<ConfigField> makeTable()
{
  using C = Config;
  return {
      real("sensor_height", &C::sensor_height, 0.01, 100.0, "m", "Height of the optical centre above the floor"),
      real("sensor_pitch", &C::sensor_pitch, -kPi / 2, kPi / 2, "rad", "Static tilt of the sensor on the base, + looks down"),
      real("sensor_roll", &C::sensor_roll, -kPi, kPi, "rad", "Static roll of the sensor on the base, + right side down, +-pi upside down"),
      real("ceiling_height", &C::ceiling_height, 0.02, 100.0, "m", "Height of the ceiling plane above the floor; above sensor_height"),
      real("max_depth", &C::max_depth, 0.1, 1000.0, "m", "Depth of 8-bit value 255 (8-bit normalised input)"),
      choice("geometry", {"exact", "thesis"}, "Plane prediction: 'exact' (pinhole ray / plane) or 'thesis' (eq 4.10-4.18)",
             [](const C& c) { return toString(c.geometry); },
             [](C& c, const std::string& v) { c.geometry = geometryFromString(v); }),
      choice("projection", {"horizontal", "column"}, "Pixel to beam: 'horizontal' (gravity-aligned range) or 'column' (thesis)",
             [](const C& c) { return toString(c.projection); },
             [](C& c, const std::string& v) { c.projection = projectionFromString(v); }),
      integer("open_kernel_size", &C::open_kernel_size, 0, 31, "px", "Opening kernel size: 0 or 1 = off, else odd"),
      choice("open_kernel_shape", {"rect", "cross", "ellipse"}, "Opening kernel shape",
             [](const C& c) { return toString(c.open_kernel_shape); },
             [](C& c, const std::string& v) { c.open_kernel_shape = kernelShapeFromString(v); }),
      real("speckle_jump", &C::speckle_jump, 0.0, 10.0, "-",
           "Wrong matches of stereo cameras: a pixel nearer, by more than this fraction of its depth, than each of the four pixels two steps away is taken as no measurement; 0 = off"),
      row("threshold_curve", FieldKind::kCurve, 0, 0, "m",
          "Threshold t(d) as 'depth:threshold, ...' control points; depths increasing, thresholds non-decreasing"),
      real("range_min", &C::range_min, 0.0, 1000.0, "m", "Shorter beams are reported as -Inf (REP 117)"),
      real("range_max", &C::range_max, 0.0, 1000.0, "m", "Longer beams are reported as +Inf; above range_min"),
      integer("scan_beams", &C::scan_beams, 0, 100000, "-", "Number of beams; 0 = the image width"),
      real("scan_fov", &C::scan_fov, 0.0, 2 * kPi, "rad", "Angular width of the scan, centred on forward; 0 = the camera's"),
      real("surface_band", &C::surface_band, 0.0, 10.0, "-",
           "Beam range: 0 = nearest kept pixel; > 0 = mean of the beam's ranges within surface_band * t(r) of its nearest"),
      flag("cliff_scan", &C::cliff_scan, "Fill the cliff scan: the nearest below-floor pixel (hole, stair down) per beam"),
      flag("cliff_in_scan", &C::cliff_in_scan, "Also put below-floor beams into the scan as obstacles"),
      integer("cliff_min_pixels", &C::cliff_min_pixels, 1, 100000, "px", "Below-floor pixels a beam needs before it reports a cliff"),
      real("cliff_min_drop", &C::cliff_min_drop, 0.0, 10.0, "m",
           "Smallest drop a cliff beam reports: below-floor pixels this far below the floor, where t(d) resolves it; 0 = all"),
      integer("confidence_window", &C::confidence_window, 1, 1000, "frames", "Ranges in each beam's rolling mean, this one included"),
      real("confidence_distance", &C::confidence_distance, 0.001, 100.0, "m",
           "d_threshold of eq 4.23: distance from the mean at which intensity is 0"),
      real("min_intensity", &C::min_intensity, 0.0, 1.0, "-", "Intensity at or below which a filtered beam becomes NaN"),
      flag("intensity_filter", &C::intensity_filter, "NaN the finite beams with intensity <= min_intensity"),
      flag("refine_floor", &C::refine_floor, "Correct the pose from the frame's own floor before predicting the planes"),
      real("floor_max_height_error", &C::floor_max_height_error, 0.001, 1.0, "m",
           "Largest correction of the sensor height by the floor fit (and the band it searches)"),
      real("floor_max_pitch_error", &C::floor_max_pitch_error, 0.0001, 0.5, "rad", "Largest correction of the pitch by the floor fit"),
      real("floor_max_roll_error", &C::floor_max_roll_error, 0.0001, 0.5, "rad", "Largest correction of the roll by the floor fit"),
      integer("floor_min_pixels", &C::floor_min_pixels, 1, 100000000, "px", "Fewest image pixels on the fitted floor to accept the fit"),
      real("floor_learn_time", &C::floor_learn_time, 0.0, 3600.0, "s", "Time constant of the learned floor correction; 0 = learn nothing"),
      real("floor_profile_max", &C::floor_profile_max, 0.0, 0.5, "m",
           "Largest height by which the learned floor profile (the floor the sensor sees, per band of range) departs from the plane; 0 = none"),
      integer("num_threads", &C::num_threads, 0, 1024, "-", "OpenMP threads for one frame; 0 = OpenMP's default"),
  };
}

/** The shortest text that reads back as exactly @p v (15 to 17 significant digits). */
std::string full(double v)
{
  for (int digits = 15;; ++digits)
  {
    std::ostringstream s;
    s << std::setprecision(digits) << v;
    if (digits == std::numeric_limits<double>::max_digits10 || std::stod(s.str()) == v)
      return s.str();
  }
}
}  // namespace

const std::vector<ConfigField>& configFields()
{
  static const std::vector<ConfigField> table = makeTable();
  return table;
}

const ConfigField& configField(const std::string& name)
{
  for (const ConfigField& f : configFields())
    if (name == f.name)
      return f;
  std::string known;
  for (const ConfigField& f : configFields())
    known += (known.empty() ? "" : ", ") + std::string(f.name);
  throw std::invalid_argument("Config: unknown field '" + name + "'; the fields are " + known);
}

double ConfigField::number(const Config& c) const
{
  switch (kind)
  {
    case FieldKind::kReal:
      return c.*real;
    case FieldKind::kInteger:
      return c.*integer;
    case FieldKind::kFlag:
      return c.*flag ? 1.0 : 0.0;
    default:
      throw std::logic_error(std::string("Config.") + name + " is not a number");
  }
}

void ConfigField::setNumber(Config& c, double v) const
{
  std::ostringstream s;
  s << "Config." << name << " = " << v << ": expected ";
  switch (kind)
  {
    case FieldKind::kReal:
      c.*real = v;
      return;
    case FieldKind::kInteger:
      if (!(v == std::floor(v)))
        throw std::invalid_argument(s.str() + "a whole number");
      if (!(std::fabs(v) <= std::numeric_limits<int>::max()))
        throw std::invalid_argument(rangeProblem(v));
      c.*integer = static_cast<int>(v);
      return;
    case FieldKind::kFlag:
      if (v != 0.0 && v != 1.0)
        throw std::invalid_argument(s.str() + "true or false");
      c.*flag = v != 0.0;
      return;
    default:
      throw std::invalid_argument(s.str() + "text: " + doc);
  }
}

std::string ConfigField::text(const Config& c) const
{
  if (kind == FieldKind::kCurve)
    return formatThresholdCurve(c.threshold_curve);
  if (kind == FieldKind::kChoice)
    return choice_of(c);
  if (kind == FieldKind::kFlag)
    return c.*flag ? "true" : "false";
  return full(number(c));
}

void ConfigField::setText(Config& c, const std::string& v) const
{
  if (kind == FieldKind::kCurve)
    c.threshold_curve = parseThresholdCurve(v);
  else if (kind == FieldKind::kChoice)
    set_choice(c, v);
  else if (kind == FieldKind::kFlag && (v == "true" || v == "false"))
    c.*flag = v == "true";
  else
  {
    std::size_t used = 0;
    double x = std::numeric_limits<double>::quiet_NaN();
    try
    {
      x = std::stod(v, &used);
    }
    catch (const std::logic_error&)
    {
      used = 0;
    }
    if (used == 0 || used != v.size())
      throw std::invalid_argument(std::string("Config.") + name + " = '" + v + "': expected a number [" + unit + "]");
    setNumber(c, x);
  }
}

std::string ConfigField::rangeProblem(const Config& c) const
{
  if (kind != FieldKind::kReal && kind != FieldKind::kInteger)
    return "";
  return rangeProblem(number(c));
}

std::string ConfigField::rangeProblem(double v) const
{
  if (std::isfinite(v) && v >= lo && v <= hi)
    return "";
  std::ostringstream s;
  s << "Config." << name << " = " << v << ": expected " << (kind == FieldKind::kInteger ? "an integer" : "a value")
    << " in [" << lo << ", " << hi << "]" << (std::string(unit) == "-" ? "" : " " + std::string(unit)) << " ("
    << doc << ")";
  return s.str();
}

}  // namespace kinect_pipeline
