// Binding of the config table (model/config_table.h: every field an attribute), the threshold curve and the sensor
// presets.
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "arrays.h"
#include "bind.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/config_table.h"
#include "kinect_pipeline/model/sensor_model.h"
#include "kinect_pipeline/model/threshold_curve.h"

namespace kinect_pipeline::python
{
namespace
{

/** The threshold curve from 'd:t, ...' text or (depth, threshold) pairs. @throw py::type_error for other types. */
std::vector<CurvePoint> curveOf(const py::handle& v)
{
  if (py::isinstance<py::str>(v))
    return parseThresholdCurve(py::cast<std::string>(v));
  std::vector<CurvePoint> pts;
  try
  {
    if (!py::isinstance<py::iterable>(v))
      throw py::cast_error();
    for (const auto& p : v)
    {
      auto pair = py::cast<std::pair<double, double>>(p);
      pts.push_back({pair.first, pair.second});
    }
  }
  catch (const py::cast_error&)
  {
    throw py::type_error("threshold_curve = " + std::string(py::repr(v)) + " (" + typeName(v) +
                         "): expected 'd:t, ...' text or (depth, threshold) pairs [m]");
  }
  validateThresholdCurve(pts);
  return pts;
}

/** A field's value as Python sees it (float, int, bool, str, or the curve as (depth, threshold) pairs). */
py::object fieldValue(const Config& c, const ConfigField& f)
{
  switch (f.kind)
  {
    case FieldKind::kReal:
      return py::float_(c.*f.real);
    case FieldKind::kInteger:
      return py::int_(c.*f.integer);
    case FieldKind::kFlag:
      return py::bool_(c.*f.flag);
    case FieldKind::kChoice:
      return py::str(f.text(c));
    case FieldKind::kCurve:
      break;
  }
  py::list out;
  for (const auto& p : c.threshold_curve)
    out.append(py::make_tuple(p.depth, p.threshold));
  return out;
}

/** "a number [m]", "an integer [px]", "True or False", ...: what a field takes, for type errors. */
std::string expectedOf(const ConfigField& f)
{
  switch (f.kind)
  {
    case FieldKind::kReal:
      return std::string("a number [") + f.unit + "]";
    case FieldKind::kInteger:
      return std::string("an integer [") + f.unit + "]";
    case FieldKind::kFlag:
      return "True or False";
    case FieldKind::kChoice:
      return "a name (str)";
    case FieldKind::kCurve:
      break;
  }
  return "'d:t, ...' text or (depth, threshold) pairs [m]";
}

void setFieldValue(Config& c, const ConfigField& f, const py::handle& v)
{
  switch (f.kind)
  {
    case FieldKind::kReal:
      c.*f.real = py::cast<double>(v);
      return;
    case FieldKind::kInteger:
      if (py::isinstance<py::bool_>(v))
        throw py::cast_error();  // True was taken as 1
      if (py::isinstance<py::int_>(v))
        f.setNumber(c, py::cast<double>(v));  // beyond int's range: named with the field's range, not as a type
      else
        c.*f.integer = py::cast<int>(v);
      return;
    case FieldKind::kFlag:
      c.*f.flag = flagOf(v, std::string("Config.") + f.name);  // None or 0.5 were taken for their truth
      return;
    case FieldKind::kChoice:
      f.setText(c, py::cast<std::string>(v));
      return;
    case FieldKind::kCurve:
      c.threshold_curve = curveOf(v);
      return;
  }
}

/** setFieldValue, with a type mismatch named: "Config.x = 'abc' (str): expected a number [m]". */
void setField(Config& c, const ConfigField& f, const py::handle& v)
{
  try
  {
    setFieldValue(c, f, v);
  }
  catch (const py::cast_error&)
  {
    throw py::type_error(std::string("Config.") + f.name + " = " + std::string(py::repr(v)) + " (" + typeName(v) +
                         "): expected " + expectedOf(f));
  }
}

const ConfigField& fieldNamed(const std::string& name)
{
  try
  {
    return configField(name);
  }
  catch (const std::invalid_argument& e)
  {
    throw py::type_error(e.what());
  }
}

/** "Height of ... [m], 0.01..100, default 1.1": a field's docstring, from the table and the defaults. */
std::string fieldDoc(const ConfigField& f)
{
  std::ostringstream s;
  s << f.doc << " [" << f.unit << "]";
  if (f.kind == FieldKind::kReal || f.kind == FieldKind::kInteger)
    s << ", " << f.lo << ".." << f.hi;
  if (f.kind == FieldKind::kChoice)
  {
    s << ": ";
    for (std::size_t i = 0; i < f.choices.size(); ++i)
      s << (i ? ", " : "") << "'" << f.choices[i] << "'";
  }
  s << " (default " << f.text(Config{}) << ")";
  return s.str();
}

/** The table as Python data: [{'name', 'kind', 'min', 'max', 'unit', 'doc', 'choices', 'default'}, ...]. */
py::list fieldTable()
{
  static const char* kinds[] = {"real", "integer", "flag", "choice", "curve"};
  py::list out;
  const Config defaults;
  for (const ConfigField& f : configFields())
  {
    py::dict row;
    row["name"] = f.name;
    row["kind"] = kinds[static_cast<int>(f.kind)];
    row["min"] = f.lo;
    row["max"] = f.hi;
    row["unit"] = f.unit;
    row["doc"] = f.doc;
    row["choices"] = f.choices;
    row["default"] = fieldValue(defaults, f);
    out.append(row);
  }
  return out;
}

/** Config(**fields): the preset of sensor_model first (fields given explicitly kept), then each field. */
Config configOf(const py::kwargs& kw)
{
  Config c;
  if (kw.contains("sensor_model"))
  {
    std::vector<std::string> given;
    for (const auto& item : kw)
      given.push_back(py::cast<std::string>(item.first));
    const py::handle model = kw["sensor_model"];
    if (!py::isinstance<py::str>(model))
      throw py::type_error("Config.sensor_model = " + std::string(py::repr(model)) + " (" + typeName(model) +
                           "): expected a sensor preset's name (str)");
    applySensorModel(py::cast<std::string>(model), c, given);
  }
  for (const auto& item : kw)
    if (py::cast<std::string>(item.first) != "sensor_model")
      setField(c, fieldNamed(py::cast<std::string>(item.first)), item.second);
  c.validate();
  return c;
}

void bindConfigClass(py::module_& m)
{
  py::class_<Config> config(m, "Config", "Pipeline parameters; field names are the ROS parameter names (SI units).");
  config
      .def(py::init(&configOf),
           "Config(**fields): the defaults with these fields changed (names as the ROS parameters); "
           "sensor_model=NAME first applies that sensor's preset (threshold_curve, range_max, cliff_min_pixels, "
           "speckle_jump), "
           "which fields given explicitly override.")
      .def_property_readonly("threshold_curve_text",
                             [](const Config& c) { return formatThresholdCurve(c.threshold_curve); })
      .def("validate", &Config::validate, "Raises ValueError naming the field, its value and the allowed range.")
      .def("to_dict",
           [](const Config& c) {
             py::dict d;  // the values as the ROS parameters hold them: the curve as its text
             for (const ConfigField& f : configFields())
               d[f.name] = f.kind == FieldKind::kCurve ? py::str(f.text(c)) : fieldValue(c, f);
             return d;
           })
      .def("__repr__", [](const Config& c) {
        std::string s = "Config(";
        for (const ConfigField& f : configFields())
          s += (&f == &configFields().front() ? "" : ", ") + std::string(f.name) + "=" +
               std::string(py::repr(fieldValue(c, f)));
        return s + ")";
      });
  // Every field an attribute, from the one table (model/config_table.h), with its docstring.
  for (const ConfigField& f : configFields())
  {
    const ConfigField* row = &f;
    config.def_property(
        f.name, [row](const Config& c) { return fieldValue(c, *row); },
        [row](Config& c, const py::object& v) { setField(c, *row, v); });
    config.attr("__dict__")[f.name].attr("__doc__") = fieldDoc(f);
  }
  m.attr("CONFIG_FIELDS") = fieldTable();
}

void bindCurve(py::module_& m)
{
  m.def(
      "threshold_lut",
      [](const py::object& curve, const std::string& encoding, double max_depth) {
        const std::vector<CurvePoint> points = curveOf(curve);
        Config c;  // the table's depth scale is Config.max_depth's: the same range
        c.max_depth = max_depth;
        if (const std::string problem = configField("max_depth").rangeProblem(c); !problem.empty())
          throw py::value_error("threshold_lut: " + problem);
        ThresholdLut lut;
        lut.build(points, encodingFromString(encoding), max_depth);
        return vecToArray(lut.table());
      },
      py::arg("curve"), py::arg("encoding"), py::arg("max_depth") = 12.0,
      "The threshold lookup table the pipeline uses (8UC1: by value; others: by 1 cm cell).");
  m.def(
      "evaluate_curve",
      [](const py::object& curve, double depth) {
        if (std::isnan(depth))
          throw py::value_error("evaluate_curve: depth = nan: expected a depth [m]");
        return evaluateCurve(curveOf(curve), depth);
      },
      py::arg("curve"), py::arg("depth"),
      "t(depth) [m] of a threshold curve ('d:t, ...' text or (depth, threshold) pairs) by piecewise-linear "
      "interpolation, flat beyond the ends; depth may also be an array of depths [m].");
  m.def(
      "evaluate_curve",
      [](const py::object& curve, const py::object& depth) {
        const auto given = py::array::ensure(depth);  // numpy's asarray: lists too
        if (!given || (given.dtype().kind() != 'f' && given.dtype().kind() != 'i' && given.dtype().kind() != 'u'))
          throw py::type_error("evaluate_curve: depth = " + std::string(py::repr(depth)) + " (" + typeName(depth) +
                               "): expected a number or an array of numbers [m]");
        const auto depths = py::array_t<double, py::array::forcecast>::ensure(given);
        const std::vector<CurvePoint> points = curveOf(curve);
        py::array_t<double> out(depths.request().shape);
        const double* in = depths.data();
        double* o = out.mutable_data();
        for (py::ssize_t i = 0; i < depths.size(); ++i)
        {
          if (std::isnan(in[i]))
            throw py::value_error("evaluate_curve: depth [" + std::to_string(i) + "] = nan: expected a depth [m]");
          o[i] = evaluateCurve(points, in[i]);
        }
        return out;
      },
      py::arg("curve"), py::arg("depth"));
  m.def("default_threshold_curve", []() { return formatThresholdCurve(defaultThresholdCurve()); });
}

/** A sensor preset as Python data (sensor_model()). */
py::dict presetDict(const SensorModel& sm)
{
  py::dict d;
  d["name"] = sm.name;
  d["description"] = sm.description;
  d["source"] = sm.source;
  d["sigma0"] = sm.noise.sigma0;
  d["quad"] = sm.noise.quad;
  d["z0"] = sm.noise.z0;
  d["step2"] = sm.noise.step2;
  d["k"] = sm.noise.k;
  d["steps"] = sm.noise.steps;
  d["margin"] = sm.noise.margin;
  d["threshold_curve"] = formatThresholdCurve(sm.thresholdCurve());
  d["range_max"] = sm.range_max;
  d["cliff_min_pixels"] = sm.cliffMinPixels();
  d["speckle_jump"] = sm.speckle_jump;
  d["camera"] = sm.camera;
  d["driver"] = sm.driver;
  d["camera_ns"] = sm.camera_ns;
  d["image"] = sm.image;
  d["depth_topic"] = sm.depthTopic();
  d["info_topic"] = sm.infoTopic();
  return d;
}

void bindSensorModels(py::module_& m)
{
  m.def(
      "sensor_models",
      []() {
        py::list out;
        for (const SensorModel& sm : sensorModels())
          out.append(sm.name);
        return out;
      },
      "Names of the sensor presets (sensor_model), the default first.");
  m.def(
      "sensor_model", [](const std::string& name) { return presetDict(sensorModel(name)); }, py::arg("name"),
      "A sensor preset as a dict: its noise model (sigma(z) = sigma0 + quad (z - z0)^2 [m], depth step step2 z^2, "
      "t(z) = margin + k sigma + steps * step), threshold_curve, range_max [m], cliff_min_pixels, typical camera, "
      "driver, camera_ns, image, depth_topic and info_topic. ValueError naming the valid names.");
  m.def(
      "sensor_sigma",
      [](const std::string& name, const py::object& z) {
        const NoiseModel noise = sensorModel(name).noise;
        return py::vectorize([noise](double d) { return noise.sigma(d); })(z);
      },
      py::arg("name"), py::arg("z"),
      "The random depth error sigma(z) [m] of a sensor preset at depth z [m] (arrays too).");
}

}  // namespace

void bindConfig(py::module_& m)
{
  bindConfigClass(m);
  bindCurve(m);
  bindSensorModels(m);
}

}  // namespace kinect_pipeline::python
