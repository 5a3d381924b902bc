// pybind11 binding of the ROS-free core: kinect_pipeline._core.
#include <algorithm>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <limits>
#include <mutex>
#include <optional>
#include <sstream>
#include <stdexcept>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "kinect_pipeline/io/compressed_depth.h"
#include "kinect_pipeline/io/depth_image.h"
#include "kinect_pipeline/io/visualize.h"
#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/config_table.h"
#include "kinect_pipeline/model/pose.h"
#include "kinect_pipeline/model/sensor_model.h"
#include "kinect_pipeline/model/threshold_curve.h"
#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/stages/opening_kernels.h"
#include "kinect_pipeline/tools/calibration.h"
#include "kinect_pipeline/tools/synthetic.h"

namespace py = pybind11;
using namespace kinect_pipeline;

namespace
{

int cvTypeOf(const py::dtype& dt)
{
  // By kind and size, not identity: '<u2' read from a buffer is uint16 too.
  const char kind = dt.kind();
  const auto size = dt.itemsize();
  if (kind == 'u' && size == 1)
    return CV_8UC1;
  if (kind == 'u' && size == 2)
    return CV_16UC1;
  if (kind == 'f' && size == 4)
    return CV_32FC1;
  return -1;
}

/** A 2-D numpy array as a cv::Mat. Zero-copy when rows are positive-strided and pixels adjacent;
 *  otherwise a C-contiguous copy is made (kept alive in @p keep). */
cv::Mat asMat(const py::handle& obj, const char* what, py::object& keep, int* cv_type = nullptr)
{
  if (!py::isinstance<py::array>(obj))
    throw py::type_error(std::string(what) + ": expected a numpy array, got " +
                         std::string(py::str(py::type::handle_of(obj).attr("__name__"))));
  py::array arr = py::reinterpret_borrow<py::array>(obj);
  const int type = cvTypeOf(arr.dtype());
  if (type < 0)
    throw py::type_error(std::string(what) + ": dtype " + std::string(py::str(arr.dtype())) +
                         ": expected uint8 (normalised), uint16 (mm) or float32 (m)");
  if (arr.ndim() != 2)
  {
    std::ostringstream s;
    s << what << ": " << arr.ndim() << "-D array: expected a 2-D (height, width) depth image";
    throw py::value_error(s.str());
  }
  if (arr.shape(0) == 0 || arr.shape(1) == 0)
  {
    std::ostringstream s;
    s << what << ": empty array of shape (" << arr.shape(0) << ", " << arr.shape(1) << ")";
    throw py::value_error(s.str());
  }
  const auto item = static_cast<py::ssize_t>(arr.itemsize());
  const py::module_ np = py::module_::import("numpy");
  if (!py::cast<bool>(arr.dtype().attr("isnative")))
    arr = py::array::ensure(arr.attr("astype")(arr.dtype().attr("newbyteorder")("=")));
  if (arr.strides(1) != item || arr.strides(0) < item * arr.shape(1))
  {
    arr = py::array::ensure(np.attr("ascontiguousarray")(arr));
  }
  keep = arr;
  if (cv_type)
    *cv_type = type;
  return cv::Mat(static_cast<int>(arr.shape(0)), static_cast<int>(arr.shape(1)), type,
                 const_cast<void*>(arr.data()), static_cast<std::size_t>(arr.strides(0)));
}

py::array matToArray(const cv::Mat& m)
{
  py::dtype dt = m.type() == CV_8UC1 ? py::dtype::of<std::uint8_t>()
                 : m.type() == CV_16UC1 ? py::dtype::of<std::uint16_t>()
                 : m.type() == CV_16SC1 ? py::dtype::of<std::int16_t>()
                                        : py::dtype::of<float>();
  py::array out(dt, {m.rows, m.cols});
  for (int r = 0; r < m.rows; ++r)
    std::memcpy(static_cast<char*>(out.mutable_data(r, 0)), m.ptr(r), m.cols * m.elemSize());
  return out;
}

py::array_t<float> vecToArray(const std::vector<float>& v)
{
  py::array_t<float> a(static_cast<py::ssize_t>(v.size()));
  std::copy(v.begin(), v.end(), a.mutable_data());
  return a;
}

std::string typeName(const py::handle& obj) { return py::str(py::type::handle_of(obj).attr("__name__")); }

/** A CompressedImage's data as bytes: bytes, bytearray, memoryview or a 1-D uint8 array (what rosbags gives). */
py::buffer_info asBytes(const py::object& obj, const char* what, py::object& keep)
{
  const char* expected = ": expected bytes, bytearray, memoryview or a 1-D uint8 numpy array";
  keep = obj;
  if (py::isinstance<py::array>(obj))
  {
    py::array a = py::reinterpret_borrow<py::array>(obj);
    if (a.ndim() != 1 || a.dtype().kind() != 'u' || a.itemsize() != 1)
      throw py::type_error(std::string(what) + ": " + std::to_string(a.ndim()) + "-D array of dtype " +
                           std::string(py::str(a.dtype())) + expected);
    keep = py::module_::import("numpy").attr("ascontiguousarray")(a);
  }
  else if (!py::isinstance<py::bytes>(obj) && !py::isinstance<py::bytearray>(obj) &&
           !py::isinstance<py::memoryview>(obj))
  {
    throw py::type_error(std::string(what) + ": " + typeName(obj) + expected);
  }
  py::buffer_info info = py::reinterpret_borrow<py::buffer>(keep).request();
  if (info.itemsize != 1 || info.ndim != 1 || (info.shape[0] > 1 && info.strides[0] != 1))
    throw py::type_error(std::string(what) + ": a " + std::to_string(info.ndim) + "-D view of " +
                         std::to_string(info.itemsize) + "-byte items" + expected + " (contiguous)");
  return info;
}

/** What process() returns; numpy arrays own their memory. */
struct PyResult
{
  py::array depth, labels;
  py::array_t<float> ranges, intensities, cliff_ranges;
  float angle_min, angle_max, angle_increment, range_min, range_max;
  py::dict counts, times;
  SensorPose pose{0.0, 0.0, 0.0};
  FloorFitResult floor_fit;
};

struct PyPipeline
{
  PyPipeline(const Camera& c, const Config& cfg, bool reference_paths)
      : pipe(c, cfg, reference_paths ? ReferencePaths::all() : ReferencePaths{})
  {
  }
  Pipeline pipe;
  FrameResult result;
  std::mutex mutex;  // process() releases the GIL: one frame at a time per instance
};

double stampOf(const py::object& stamp)
{
  if (stamp.is_none())
    return std::numeric_limits<double>::quiet_NaN();
  const double t = py::cast<double>(stamp);
  if (!std::isfinite(t))
    throw py::value_error("stamp = " + std::string(py::repr(stamp)) + ": expected a finite time in seconds or None");
  return t;
}

double poseTerm(const SensorPose& p, int i)
{
  if (i < -3 || i > 2)
    throw py::index_error("pose index " + std::to_string(i) + ": expected 0 (height), 1 (pitch) or 2 (roll)");
  const double v[3] = {p.height, p.pitch, p.roll};
  return v[(i + 3) % 3];
}

std::string describeTerms(const std::string& name, double h, double p, double r)
{
  std::ostringstream s;
  s << name << "(height=" << h << " m, pitch=" << p << " rad, roll=" << r << " rad)";
  return s.str();
}

/** Depth in float32 is metres: an image whose valid pixels have a median above this is plainly millimetres. */
constexpr float kMillimetreMedian = 100.0f;

/** @throw py::value_error for a float32 depth image that is plainly millimetres (median of its valid pixels,
 *  on a subsample, above kMillimetreMedian). */
void refuseMillimetreFloats(const cv::Mat& m)
{
  if (m.type() != CV_32FC1)
    return;
  std::vector<float> v;
  const int step = std::max(1, static_cast<int>(std::sqrt(static_cast<double>(m.total()) / 4096.0)));
  for (int r = 0; r < m.rows; r += step)
  {
    const float* row = m.ptr<float>(r);
    for (int u = 0; u < m.cols; u += step)
      if (row[u] > 0.0f && std::isfinite(row[u]))
        v.push_back(row[u]);
  }
  if (v.empty())
    return;
  std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
  const float median = v[v.size() / 2];
  if (median > kMillimetreMedian)
  {
    std::ostringstream s;
    s << "depth: float32 with a median of " << median << " over its valid pixels: that is millimetres, not metres "
      << "(a float32 depth image is in metres: divide it by 1000, or pass the uint16 millimetres as they are)";
    throw py::value_error(s.str());
  }
}

std::string describeResult(const PyResult& r)
{
  std::ostringstream s;
  s.setf(std::ios::fixed);
  const auto shape = r.depth.request().shape;
  const py::array_t<float>& ranges = r.ranges;
  const float* a = ranges.data();
  int finite = 0;
  float nearest = std::numeric_limits<float>::infinity();
  for (py::ssize_t i = 0; i < ranges.size(); ++i)
    if (std::isfinite(a[i]))
    {
      ++finite;
      nearest = std::min(nearest, a[i]);
    }
  int cliffs = 0;
  for (py::ssize_t i = 0; i < r.cliff_ranges.size(); ++i)
    cliffs += std::isfinite(r.cliff_ranges.data()[i]) ? 1 : 0;
  double total = 0.0;
  for (const auto& item : r.counts)
    total += py::cast<double>(item.second);
  s << "Result(" << shape[1] << "x" << shape[0] << " " << std::string(py::str(r.depth.dtype())) << ", "
    << ranges.size() << " beams: " << finite << " finite";
  if (finite)
    s << std::setprecision(2) << ", nearest " << nearest << " m";
  s << ", " << cliffs << " cliff; pixels";
  for (const auto& item : r.counts)
    s << " " << std::string(py::str(item.first)) << " " << std::setprecision(1)
      << (total > 0 ? 100.0 * py::cast<double>(item.second) / total : 0.0) << " %";
  s << "; " << std::setprecision(3) << py::cast<double>(r.times["total"]) << " ms)";
  return s.str();
}


template <typename F>
PyResult runFrame(PyPipeline& self, const py::object& depth, F&& call)
{
  py::object keep;
  cv::Mat in = asMat(depth, "depth", keep);
  refuseMillimetreFloats(in);
  PyResult res;
  // Outputs are fresh numpy arrays; the core writes straight into them.
  py::dtype dt = py::reinterpret_borrow<py::array>(keep).dtype();
  res.depth = py::array(dt, {in.rows, in.cols});
  res.labels = py::array(py::dtype::of<std::uint8_t>(), {in.rows, in.cols});
  void* depth_out = res.depth.mutable_data();  // numpy calls need the GIL
  void* labels_out = res.labels.mutable_data();
  FrameResult fr;
  {
    py::gil_scoped_release release;
    std::lock_guard<std::mutex> lock(self.mutex);
    self.result.depth = cv::Mat(in.rows, in.cols, in.type(), depth_out);
    self.result.labels = cv::Mat(in.rows, in.cols, CV_8UC1, labels_out);
    call(in, self.result);
    fr.scan = self.result.scan;  // copied under the lock: another thread may process next
    fr.cliff = self.result.cliff;
    fr.counts = self.result.counts;
    fr.times = self.result.times;
    fr.pose = self.result.pose;
    fr.floor_fit = self.result.floor_fit;
    if (self.result.depth.data != depth_out || self.result.labels.data != labels_out)
      throw std::logic_error("kinect_pipeline: the core reallocated its output");
  }
  res.ranges = vecToArray(fr.scan.ranges);
  res.intensities = vecToArray(fr.scan.intensities);
  res.cliff_ranges = vecToArray(fr.cliff.ranges);
  res.angle_min = fr.scan.angle_min;
  res.angle_max = fr.scan.angle_max;
  res.angle_increment = fr.scan.angle_increment;
  res.range_min = fr.scan.range_min;
  res.range_max = fr.scan.range_max;
  for (int k = 0; k < kNumLabels; ++k)
    res.counts[kLabelNames[k]] = fr.counts[k];
  res.pose = fr.pose;
  res.floor_fit = fr.floor_fit;
  res.times["prepare"] = fr.times.prepare;
  res.times["floor_fit"] = fr.times.floor_fit;
  res.times["erode"] = fr.times.erode;
  res.times["classify_scan"] = fr.times.classify_scan;
  res.times["confidence"] = fr.times.confidence;
  res.times["total"] = fr.times.total;
  return res;
}



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
    throw py::type_error("threshold_curve = " + std::string(py::repr(v)) + " (" +
                         std::string(py::str(v.get_type().attr("__name__"))) +
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

void setFieldValue(Config& c, const ConfigField& f, const py::handle& v);

/** setFieldValue, with a type mismatch named: "Config.x = 'abc' (str): expected a number [m]". */
void setField(Config& c, const ConfigField& f, const py::handle& v)
{
  try
  {
    setFieldValue(c, f, v);
  }
  catch (const py::cast_error&)
  {
    throw py::type_error(std::string("Config.") + f.name + " = " + std::string(py::repr(v)) + " (" +
                         std::string(py::str(v.get_type().attr("__name__"))) + "): expected " + expectedOf(f));
  }
}

void setFieldValue(Config& c, const ConfigField& f, const py::handle& v)
{
  switch (f.kind)
  {
    case FieldKind::kReal:
      c.*f.real = py::cast<double>(v);
      return;
    case FieldKind::kInteger:
      c.*f.integer = py::cast<int>(v);
      return;
    case FieldKind::kFlag:
      c.*f.flag = py::cast<bool>(v);
      return;
    case FieldKind::kChoice:
      f.setText(c, py::cast<std::string>(v));
      return;
    case FieldKind::kCurve:
      c.threshold_curve = curveOf(v);
      return;
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

}  // namespace

PYBIND11_MODULE(_core, m)
{
  m.doc() = "ROS-free core of kinect_pipeline (C++/OpenMP). Use the kinect_pipeline package, not this module.";

  py::class_<Camera>(m, "Camera", "Pinhole depth camera model [px] (optical frame: x right, y down, z forward).")
      .def(py::init<int, int, double, double, double, double>(), py::arg("width"), py::arg("height"),
           py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"))
      .def_static("from_fov", &Camera::fromFov, py::arg("width"), py::arg("height"), py::arg("hfov"),
                  py::arg("vfov"), "Camera from fields of view [rad], edge to edge; principal point in the centre.")
      .def_readonly("width", &Camera::width)
      .def_readonly("height", &Camera::height)
      .def_readonly("fx", &Camera::fx)
      .def_readonly("fy", &Camera::fy)
      .def_readonly("cx", &Camera::cx)
      .def_readonly("cy", &Camera::cy)
      .def_property_readonly("hfov", &Camera::hfov)
      .def_property_readonly("vfov", &Camera::vfov)
      .def("__repr__", [](const Camera& c) { return "Camera(" + c.describe() + ")"; });

  py::class_<Config>(m, "Config", "Pipeline parameters; field names are the ROS parameter names (SI units).")
      .def(py::init([](const py::kwargs& kw) {
             Config c;
             // sensor_model first: its fields are what the preset says, unless given explicitly.
             if (kw.contains("sensor_model"))
             {
               std::vector<std::string> given;
               for (const auto& item : kw)
                 given.push_back(py::cast<std::string>(item.first));
               applySensorModel(py::cast<std::string>(kw["sensor_model"]), c, given);
             }
             for (const auto& item : kw)
               if (py::cast<std::string>(item.first) != "sensor_model")
                 setField(c, fieldNamed(py::cast<std::string>(item.first)), item.second);
             c.validate();
             return c;
           }),
           "Config(**fields): the defaults with these fields changed (names as the ROS parameters); "
           "sensor_model=NAME first applies that sensor's preset (threshold_curve, range_max, cliff_min_pixels), "
           "which fields given explicitly override.")
      .def_property_readonly("threshold_curve_text", [](const Config& c) { return formatThresholdCurve(c.threshold_curve); })
      .def("validate", &Config::validate, "Raises ValueError naming the field, its value and the allowed range.")
      .def("to_dict", [](const Config& c) {
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
  {
    // Every field an attribute, from the one table (config_fields.h), with its docstring.
    auto config = py::reinterpret_borrow<py::class_<Config>>(m.attr("Config"));
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
  py::class_<SensorPose>(m, "SensorPose",
                         "The sensor's pose relative to the floor: height [m], pitch [rad, + looks down], roll [rad, + "
                         "right side down]. Unpacks as (height, pitch, roll).")
      .def(py::init([](double h, double p, double r) { return SensorPose{h, p, r}; }), py::arg("height"),
           py::arg("pitch"), py::arg("roll") = 0.0)
      .def_readwrite("height", &SensorPose::height)
      .def_readwrite("pitch", &SensorPose::pitch)
      .def_readwrite("roll", &SensorPose::roll)
      .def("__len__", [](const SensorPose&) { return 3; })
      .def("__getitem__", [](const SensorPose& p, int i) { return poseTerm(p, i); })
      .def("__iter__", [](const SensorPose& p) { return py::iter(py::make_tuple(p.height, p.pitch, p.roll)); })
      .def("__repr__", [](const SensorPose& p) { return describeTerms("SensorPose", p.height, p.pitch, p.roll); });
  py::class_<PoseCorrection>(m, "PoseCorrection",
                             "A correction added to a pose: height [m], pitch and roll [rad]. Unpacks as a tuple.")
      .def_readonly("height", &PoseCorrection::height)
      .def_readonly("pitch", &PoseCorrection::pitch)
      .def_readonly("roll", &PoseCorrection::roll)
      .def("__len__", [](const PoseCorrection&) { return 3; })
      .def("__getitem__", [](const PoseCorrection& c, int i) { return poseTerm(SensorPose{c.height, c.pitch, c.roll}, i); })
      .def("__iter__", [](const PoseCorrection& c) { return py::iter(py::make_tuple(c.height, c.pitch, c.roll)); })
      .def("__repr__",
           [](const PoseCorrection& c) { return describeTerms("PoseCorrection", c.height, c.pitch, c.roll); });
  py::class_<FloorFitResult>(m, "FloorFit", "What the floor refinement decided for one frame.")
      .def_property_readonly("accepted", &FloorFitResult::accepted, "the frame was processed at the fitted pose")
      .def_property_readonly(
          "reason", [](const FloorFitResult& f) { return toString(f.status); },
          "'accepted', 'off', 'too few pixels', 'spread too large', 'out of bounds' or 'ill-conditioned'")
      .def_readonly("row_step", &FloorFitResult::row_step, "the fit samples every row_step-th row")
      .def_readonly("col_step", &FloorFitResult::col_step, "and every col_step-th pixel of such a row")
      .def_readonly("candidates", &FloorFitResult::candidates, "sampled pixels in the band where the floor can be")
      .def_readonly("support", &FloorFitResult::support, "of those, the sampled pixels on the fitted floor")
      .def_readonly("pixels", &FloorFitResult::pixels,
                    "image pixels on the fitted floor (support * row_step * col_step), compared with floor_min_pixels")
      .def_readonly("spread", &FloorFitResult::spread, "RMS residual of the support in units of t(d)")
      .def_readonly("shift", &FloorFitResult::shift,
                    "the fit's largest move of the floor where seen, in t(d); below 0.1 the frame keeps the prior")
      .def_readonly("fit", &FloorFitResult::fit, "fitted pose minus the prior (also when declined)")
      .def_readonly("correction", &FloorFitResult::applied, "the frame's pose minus the prior")
      .def_readonly("learned", &FloorFitResult::learned, "the learned correction after this frame")
      .def("__repr__", [](const FloorFitResult& f) {
        std::ostringstream s;
        s << "FloorFit(reason='" << toString(f.status) << "', pixels=" << f.pixels << ", support=" << f.support << ", candidates=" << f.candidates
          << ", correction=" << describeTerms("", f.applied.height, f.applied.pitch, f.applied.roll)
          << ", learned=" << describeTerms("", f.learned.height, f.learned.pitch, f.learned.roll) << ")";
        return s.str();
      });

  py::class_<PyResult>(m, "Result", "One processed frame.")
      .def_readonly("depth", &PyResult::depth, "cleaned depth, input dtype; removed: 255 / 0 / NaN")
      .def_readonly("labels", &PyResult::labels,
                    "uint8 per pixel: 0 kept, 1 invalid, 2 floor, 3 above ceiling plane, 4 below floor")
      .def_readonly("ranges", &PyResult::ranges, "float32 [m]; +Inf no return, -Inf too close, NaN no data")
      .def_readonly("intensities", &PyResult::intensities, "float32 confidence in [0, 1]")
      .def_readonly("cliff_ranges", &PyResult::cliff_ranges,
                    "float32 [m] per beam: nearest below-floor pixel (a hole, a stair down) with at least "
                    "cliff_min_pixels in the beam; +Inf none, NaN no data; empty if cliff_scan is off")
      .def_readonly("angle_min", &PyResult::angle_min)
      .def_readonly("angle_max", &PyResult::angle_max)
      .def_readonly("angle_increment", &PyResult::angle_increment)
      .def_readonly("range_min", &PyResult::range_min)
      .def_readonly("range_max", &PyResult::range_max)
      .def_readonly("counts", &PyResult::counts, "pixels per label name")
      .def_readonly("times", &PyResult::times, "wall-clock ms per stage")
      .def_readonly("pose", &PyResult::pose, "the SensorPose the frame was processed at (the refined prior)")
      .def_readonly("floor_fit", &PyResult::floor_fit, "what the floor refinement decided (FloorFit)")
      .def("__repr__", &describeResult);

  py::class_<PyPipeline>(m, "Pipeline", "The per-frame processing. Keeps each beam's confidence history.")
      .def(py::init<const Camera&, const Config&, bool>(), py::arg("camera"), py::arg("config"),
           py::arg("reference_paths") = false,
           "reference_paths: every step on its plain reference path instead of the fast one (for checks)")
      .def(
          "process",
          [](PyPipeline& self, const py::object& depth, double base_pitch, double base_roll, const py::object& stamp) {
            const double t = stampOf(stamp);
            return runFrame(self, depth, [&](const cv::Mat& in, FrameResult& fr) {
              self.pipe.process(in, base_pitch, base_roll, fr, t);
            });
          },
          py::arg("depth"), py::arg("base_pitch") = 0.0, py::arg("base_roll") = 0.0, py::arg("stamp") = py::none(),
          "Process one frame: depth is a 2-D uint8 (normalised), uint16 (mm) or float32 (m) array; stamp [s] times "
          "the floor refinement's learning (None: 1/30 s after the last frame).")
      .def(
          "process_pose",
          [](PyPipeline& self, const py::object& depth, double height, double pitch, double roll,
             const py::object& stamp) {
            const double t = stampOf(stamp);
            return runFrame(self, depth, [&](const cv::Mat& in, FrameResult& fr) {
              self.pipe.process(in, SensorPose{height, pitch, roll}, fr, t);
            });
          },
          py::arg("depth"), py::arg("height"), py::arg("pitch"), py::arg("roll") = 0.0, py::arg("stamp") = py::none(),
          "Process one frame at a whole pose (e.g. from tf): height [m], pitch and roll [rad] of the sensor; "
          "sensor_height/pitch/roll of the config are not used.")
      .def("reset", [](PyPipeline& self) { self.pipe.reset(); },
           "Forget the confidence history and the floor refinement's learned correction.")
      .def_property_readonly(
          "learned_correction", [](PyPipeline& self) { return self.pipe.floorFit().learned(); },
          "The floor refinement's learned correction now (PoseCorrection).")
      .def_property(
          "floor_state",
          [](PyPipeline& self) {
            const FloorFit::State s = self.pipe.floorFit().state();
            return py::make_tuple(s.learned.height, s.learned.pitch, s.learned.roll,
                                  std::isfinite(s.last_stamp) ? py::cast(s.last_stamp) : py::none());
          },
          [](PyPipeline& self, const py::tuple& t) {
            if (t.size() != 4)
              throw py::value_error("floor_state: expected (height, pitch, roll, last_stamp or None), got " +
                                    std::string(py::repr(t)));
            FloorFit::State s;
            s.learned = {py::cast<double>(t[0]), py::cast<double>(t[1]), py::cast<double>(t[2])};
            s.last_stamp = t[3].is_none() ? std::numeric_limits<double>::quiet_NaN() : py::cast<double>(t[3]);
            std::lock_guard<std::mutex> lock(self.mutex);
            self.pipe.restoreFloorFit(s);
          },
          "What the floor refinement carries between frames: (learned height [m], pitch, roll [rad], the last "
          "frame's stamp [s] or None); set it to continue another run exactly (a resumed replay).")
      .def_property(
          "config", [](PyPipeline& self) { return self.pipe.config(); },
          [](PyPipeline& self, const Config& c) {
            std::lock_guard<std::mutex> lock(self.mutex);
            self.pipe.setConfig(c);
          })
      .def_property_readonly("camera", [](PyPipeline& self) { return self.pipe.camera(); })
      .def(
          "predicted_floor",
          [](PyPipeline& self) {
            const PlaneModel& p = self.pipe.planes();
            const Camera& c = self.pipe.camera();
            py::array_t<double> out({c.height, c.width});
            auto o = out.mutable_unchecked<2>();
            for (int r = 0; r < c.height; ++r)
              for (int u = 0; u < c.width; ++u)
                o(r, u) = p.floorDepth(u, r);
            return out;
          },
          "Predicted floor depth per pixel [m] (+Inf: the ray never meets it) at the last frame's pose.")
      .def(
          "predicted_ceiling",
          [](PyPipeline& self) {
            const PlaneModel& p = self.pipe.planes();
            const Camera& c = self.pipe.camera();
            py::array_t<double> out({c.height, c.width});
            auto o = out.mutable_unchecked<2>();
            for (int r = 0; r < c.height; ++r)
              for (int u = 0; u < c.width; ++u)
                o(r, u) = p.ceilingDepth(u, r);
            return out;
          },
          "Predicted ceiling-plane depth per pixel [m] (+Inf: never met) at the last frame's pose.");

  m.def(
      "threshold_lut",
      [](const py::object& curve, const std::string& encoding, double max_depth) {
        Config c;
        c.threshold_curve = curveOf(curve);
        const Encoding e = encoding == "8UC1" ? Encoding::kMono8
                           : encoding == "16UC1" ? Encoding::kMono16
                           : encoding == "32FC1" ? Encoding::kFloat32
                                                 : throw py::value_error("encoding '" + encoding + "': expected 8UC1, 16UC1 or 32FC1");
        ThresholdLut lut;
        lut.build(c.threshold_curve, e, max_depth);
        return vecToArray(lut.table());
      },
      py::arg("curve"), py::arg("encoding"), py::arg("max_depth") = 12.0,
      "The threshold lookup table the pipeline uses (8UC1: by value; others: by 1 cm cell).");
  m.def(
      "evaluate_curve",
      [](const py::object& curve, double depth) {
        Config c;
        c.threshold_curve = curveOf(curve);
        return evaluateCurve(c.threshold_curve, depth);
      },
      py::arg("curve"), py::arg("depth"),
      "t(depth) [m] of a threshold curve ('d:t, ...' text or (depth, threshold) pairs) by piecewise-linear "
      "interpolation, flat beyond the ends; depth may also be an array of depths [m].");
  m.def(
      "evaluate_curve",
      [](const py::object& curve, const py::array_t<double, py::array::forcecast>& depths) {
        Config c;
        c.threshold_curve = curveOf(curve);
        py::array_t<double> out(depths.request().shape);
        const double* in = depths.data();
        double* o = out.mutable_data();
        for (py::ssize_t i = 0; i < depths.size(); ++i)
          o[i] = evaluateCurve(c.threshold_curve, in[i]);
        return out;
      },
      py::arg("curve"), py::arg("depth"));
  m.def("default_threshold_curve", []() { return formatThresholdCurve(defaultThresholdCurve()); });
  {
    py::dict labels;  // the core's own list: Result.labels values by name
    for (int k = 0; k < kNumLabels; ++k)
      labels[kLabelNames[k]] = k;
    m.attr("LABELS") = labels;
  }

  m.def(
      "sensor_models", []() {
        py::list out;
        for (const SensorModel& sm : sensorModels())
          out.append(sm.name);
        return out;
      },
      "Names of the sensor presets (sensor_model), the default first.");
  m.def(
      "sensor_model",
      [](const std::string& name) {
        const SensorModel& sm = sensorModel(name);
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
        d["camera"] = sm.camera;
        d["driver"] = sm.driver;
        d["camera_ns"] = sm.camera_ns;
        d["image"] = sm.image;
        const std::string ns = sm.camera_ns.empty() ? "" : "/" + sm.camera_ns;
        d["depth_topic"] = ns + "/" + sm.image;
        d["info_topic"] = ns + "/" + sm.image.substr(0, sm.image.rfind('/') + 1) + "camera_info";
        return d;
      },
      py::arg("name"),
      "A sensor preset as a dict: its noise model (sigma(z) = sigma0 + quad (z - z0)^2 [m], depth step step2 z^2, "
      "t(z) = margin + k sigma + steps * step), threshold_curve, range_max [m], cliff_min_pixels, typical camera, "
      "driver, camera_ns, image, depth_topic and info_topic. ValueError naming the valid names.");
  m.def(
      "sensor_sigma",
      [](const std::string& name, const py::object& z) {
        const NoiseModel noise = sensorModel(name).noise;
        return py::vectorize([noise](double d) { return noise.sigma(d); })(z);
      },
      py::arg("name"), py::arg("z"), "The random depth error sigma(z) [m] of a sensor preset at depth z [m] (arrays too).");

  m.def("is_supported_depth_encoding", &isSupportedDepthEncoding, py::arg("encoding"),
        "True for the depth encodings the pipeline reads: 8UC1, mono8, 16UC1, mono16, 32FC1.");
  m.def(
      "depth_from_buffer",
      [](const std::string& encoding, std::uint32_t width, std::uint32_t height, std::uint32_t step,
         bool is_bigendian, const py::buffer& data) {
        const py::buffer_info info = data.request();
        ImageBuffer image{encoding, width, height, step, is_bigendian, static_cast<const std::uint8_t*>(info.ptr),
                          static_cast<std::size_t>(info.size * info.itemsize)};
        if (info.ndim != 1 && info.size > 0)
          throw py::value_error("data: expected a flat buffer of bytes");
        cv::Mat buffer;
        return matToArray(depthFromBuffer(image, buffer));
      },
      py::arg("encoding"), py::arg("width"), py::arg("height"), py::arg("step"), py::arg("is_bigendian"),
      py::arg("data"),
      "A depth image from a sensor_msgs/Image's fields (data: bytes or a uint8 array) as a new 2-D array: uint8 "
      "for 8UC1/mono8, uint16 for 16UC1/mono16 (mm), float32 for 32FC1 (m), in the host's byte order. ValueError "
      "for another encoding, empty data, a step below width * pixel size or data shorter than step * height, "
      "quoting the values (the ROS node's checks).");
  m.def(
      "camera_from_intrinsics",
      [](std::uint32_t width, std::uint32_t height, const py::object& K, const std::string& frame_id) {
        std::array<double, 9> k{};
        std::size_t n = 0;
        for (const auto& v : K)
        {
          if (n == 9)
            throw py::value_error("K: expected 9 values (row-major 3x3), got more");
          k[n++] = py::cast<double>(v);
        }
        if (n != 9)
          throw py::value_error("K: expected 9 values (row-major 3x3), got " + std::to_string(n));
        return cameraFromIntrinsics(width, height, k, frame_id);
      },
      py::arg("width"), py::arg("height"), py::arg("K"), py::arg("frame_id") = "",
      "The camera of a sensor_msgs/CameraInfo's width, height and K (fx = K[0], fy = K[4], cx = K[2], cy = K[5]); "
      "ValueError for K[0] = 0 (an uncalibrated camera), a zero size or non-finite values (the ROS node's checks).");

  m.def(
      "render_scene",
      [](const Camera& cam, double height, double pitch, double roll, const std::vector<std::array<double, 6>>& boxes,
         const std::vector<std::array<double, 4>>& holes, double hole_depth, double ceiling, bool floor) {
        Scene s;
        s.floor = floor;
        for (const auto& b : boxes)
          s.boxes.push_back({b[0], b[1], b[2], b[3], b[4], b[5]});
        for (const auto& h : holes)
          s.holes.push_back({h[0], h[1], h[2], h[3], 0.0, 0.0});
        s.hole_depth = hole_depth;
        s.ceiling = ceiling;
        Rendering r;
        {
          py::gil_scoped_release release;
          renderScene(cam, height, pitch, roll, s, r);
        }
        py::dict d;
        d["depth"] = matToArray(r.depth);
        d["height"] = matToArray(r.height);
        d["range"] = matToArray(r.range);
        d["angle"] = matToArray(r.angle);
        d["object"] = matToArray(r.object);
        return d;
      },
      py::arg("camera"), py::arg("height"), py::arg("pitch"), py::arg("roll"),
      py::arg("boxes") = std::vector<std::array<double, 6>>{}, py::arg("holes") = std::vector<std::array<double, 4>>{},
      py::arg("hole_depth") = 0.5, py::arg("ceiling") = 0.0, py::arg("floor") = true,
      "Ray-cast a scene (boxes (x0, x1, y0, y1, z0, z1) and hole footprints (x0, x1, y0, y1) in the gravity-aligned "
      "frame on the floor under the sensor). Returns dict of depth [m, +Inf none], height [m], range [m], angle [rad], "
      "object (-1 none, 0 floor, 1 ceiling, 2 hole, 10+i box i).");
  m.def(
      "add_kinect_noise",
      [](py::array_t<float, py::array::c_style> depth, std::uint64_t seed, double sigma0, double k, double dropout) {
        if (depth.ndim() != 2)
          throw py::value_error("depth: expected a 2-D float32 array");
        py::array_t<float> out({depth.shape(0), depth.shape(1)});
        std::memcpy(out.mutable_data(), depth.data(), depth.nbytes());
        cv::Mat m(static_cast<int>(out.shape(0)), static_cast<int>(out.shape(1)), CV_32FC1, out.mutable_data());
        addKinectNoise(m, seed, sigma0, k, dropout);
        return out;
      },
      py::arg("depth"), py::arg("seed"), py::arg("sigma0") = 0.0015, py::arg("k") = 0.0019, py::arg("dropout") = 0.01,
      "Copy of a float32 depth [m] with Kinect-v2-like noise sigma0 + k (z - 0.4)^2 and dropouts (+Inf).");
  using Tf = std::pair<std::array<double, 4>, std::array<double, 3>>;
  auto toRigid = [](const Tf& t) {
    RigidTransform r;
    r.q = t.first;
    r.t = t.second;
    return r;
  };
  auto fromRigid = [](const RigidTransform& r) { return Tf{r.q, r.t}; };
  m.def(
      "compose_transforms", [=](const Tf& a, const Tf& b) { return fromRigid(toRigid(a) * toRigid(b)); },
      py::arg("a"), py::arg("b"),
      "a * b for transforms given as ((qx, qy, qz, qw), (x, y, z)): parent<-child of a, then of b.");
  m.def(
      "invert_transform", [=](const Tf& a) { return fromRigid(toRigid(a).inverse()); }, py::arg("a"));
  m.def(
      "interpolate_transform", [=](const Tf& a, const Tf& b, double f) { return fromRigid(interpolate(toRigid(a), toRigid(b), f)); },
      py::arg("a"), py::arg("b"), py::arg("f"), "Linear translation, spherical rotation; f in [0, 1].");
  m.def(
      "pose_from_optical_transform",
      [=](const Tf& base_from_optical, double base_frame_height) {
        double yaw;
        const SensorPose p = poseFromOpticalTransform(toRigid(base_from_optical), base_frame_height, yaw);
        return py::make_tuple(p.height, p.pitch, p.roll, yaw);
      },
      py::arg("base_from_optical"), py::arg("base_frame_height") = 0.0,
      "(height, pitch, roll, yaw) of the sensor from its optical frame's transform in a gravity-aligned base frame.");
  m.def("roll_pitch_yaw", &rollPitchYaw, py::arg("q"), "(roll, pitch, yaw) of a quaternion (x, y, z, w).");
  m.def("quaternion_from_rpy", &quaternionFromRpy, py::arg("roll"), py::arg("pitch"), py::arg("yaw") = 0.0,
        "Quaternion (x, y, z, w) of R = Rz(yaw) Ry(pitch) Rx(roll).");
  m.def(
      "render_lidar",
      [](const std::vector<std::array<double, 6>>& boxes, double z, double angle_min, double increment, int beams,
         double range_max) {
        Scene s;
        for (const auto& b : boxes)
          s.boxes.push_back({b[0], b[1], b[2], b[3], b[4], b[5]});
        return vecToArray(renderLidar(s, z, angle_min, increment, beams, range_max));
      },
      py::arg("boxes"), py::arg("z"), py::arg("angle_min"), py::arg("increment"), py::arg("beams"),
      py::arg("range_max") = 30.0,
      "Ranges of a level planar LiDAR at height z seeing the boxes (+Inf: nothing within range_max).");
  m.def(
      "add_tof_artefacts",
      [](py::array_t<float, py::array::c_style> depth, std::uint64_t seed, double max_range, double flying, double edge_jump) {
        if (depth.ndim() != 2)
          throw py::value_error("depth: expected a 2-D float32 array");
        py::array_t<float> out({depth.shape(0), depth.shape(1)});
        std::memcpy(out.mutable_data(), depth.data(), depth.nbytes());
        cv::Mat m(static_cast<int>(out.shape(0)), static_cast<int>(out.shape(1)), CV_32FC1, out.mutable_data());
        addTofArtefacts(m, seed, max_range, flying, edge_jump);
        return out;
      },
      py::arg("depth"), py::arg("seed"), py::arg("max_range") = 8.0, py::arg("flying") = 0.5, py::arg("edge_jump") = 0.3,
      "Copy of a float32 depth [m] with pixels beyond max_range unknown (+Inf) and flying pixels at depth jumps.");
  m.def(
      "band_scan",
      [](py::array_t<float, py::array::c_style> depth, const Camera& cam, int band_rows) {
        if (depth.ndim() != 2)
          throw py::value_error("depth: expected a 2-D float32 array");
        cv::Mat m(static_cast<int>(depth.shape(0)), static_cast<int>(depth.shape(1)), CV_32FC1,
                  const_cast<float*>(depth.data()));
        return vecToArray(bandScan(m, cam, band_rows));
      },
      py::arg("depth"), py::arg("camera"), py::arg("band_rows") = 1,
      "Baseline (depthimage_to_laserscan's way): nearest depth per column in a band of rows, no floor removal.");
  m.def(
      "calibrate_from_floor",
      [](py::array_t<float, py::array::c_style> depth, const Camera& cam, double max_tilt, double min_fraction,
         double max_range, int iterations, int stride, std::uint64_t seed) {
        if (depth.ndim() != 2)
          throw py::value_error("depth: expected a 2-D float32 array [m]");
        cv::Mat m(static_cast<int>(depth.shape(0)), static_cast<int>(depth.shape(1)), CV_32FC1,
                  const_cast<float*>(depth.data()));
        CalibrationOptions o;
        o.max_tilt = max_tilt;
        o.min_fraction = min_fraction;
        o.max_range = max_range;
        o.iterations = iterations;
        o.stride = stride;
        o.seed = seed;
        FloorPose p;
        {
          py::gil_scoped_release release;
          p = calibrateFromFloor(m, cam, o);
        }
        py::dict d;
        d["found"] = p.found;
        d["height"] = p.height;
        d["pitch"] = p.pitch;
        d["roll"] = p.roll;
        d["height_std"] = p.height_std;
        d["pitch_std"] = p.pitch_std;
        d["roll_std"] = p.roll_std;
        d["floor_fraction"] = p.floor_fraction;
        d["floor_pixels"] = p.floor_pixels;
        d["rms"] = p.rms;
        return d;
      },
      py::arg("depth"), py::arg("camera"), py::arg("max_tilt") = 0.7, py::arg("min_fraction") = 0.05,
      py::arg("max_range") = 6.0, py::arg("iterations") = 400, py::arg("stride") = 2, py::arg("seed") = 1,
      "Height, pitch, roll (and 1-sigma) of the sensor from the floor seen in a float32 depth frame [m].");
  m.def(
      "kinect_sigma", py::vectorize([](double z, double sigma0, double k) { return kinectSigma(z, sigma0, k); }),
      py::arg("z"), py::arg("sigma0") = 0.0015, py::arg("k") = 0.0019,
      "Depth noise of the Kinect v2 model [m] at depth z [m] (numpy-vectorised).");
  m.def(
      "encode_depth",
      [](const py::object& metres, const std::string& encoding, double max_depth) {
        py::object keep;
        int type = 0;
        cv::Mat m = asMat(metres, "metres", keep, &type);
        if (type != CV_32FC1)
          throw py::type_error("metres: expected a float32 array");
        const int t = encoding == "8UC1" ? CV_8UC1 : encoding == "16UC1" ? CV_16UC1 : encoding == "32FC1" ? CV_32FC1 : -1;
        if (t < 0)
          throw py::value_error("encoding '" + encoding + "': expected 8UC1, 16UC1 or 32FC1");
        return matToArray(encodeDepth(m, t, max_depth));
      },
      py::arg("metres"), py::arg("encoding"), py::arg("max_depth") = 12.0,
      "Float metres -> 8UC1 normalised / 16UC1 mm / 32FC1 (unknown -> 0, NaN kept for float).");
  const CompressedDepthOptions cd_defaults;
  m.def(
      "decode_compressed_depth",
      [](const py::object& format, const py::object& data, std::optional<std::pair<int, int>> expected_shape) {
        if (!py::isinstance<py::str>(format))
          throw py::type_error("format: " + typeName(format) + ": expected a str such as '16UC1; compressedDepth png'");
        const std::string f = format.cast<std::string>();
        cv::Size expected;
        if (expected_shape)
        {
          const auto [h, w] = *expected_shape;
          if (h < 1 || w < 1)
            throw py::value_error("expected_shape = (" + std::to_string(h) + ", " + std::to_string(w) +
                                  "): expected (height, width) of at least one pixel each, or None");
          expected = cv::Size(w, h);
        }
        py::object keep;
        const py::buffer_info bytes = asBytes(data, "data", keep);
        cv::Mat depth;
        {
          py::gil_scoped_release release;
          depth = decodeCompressedDepth(f, static_cast<const std::uint8_t*>(bytes.ptr),
                                        static_cast<std::size_t>(bytes.size), expected);
        }
        return matToArray(depth);
      },
      py::arg("format"), py::arg("data"), py::arg("expected_shape") = py::none(),
      "A compressedDepth CompressedImage (its format and data: bytes or a uint8 array) as a depth image: uint16 [mm, "
      "0 unknown] for 16UC1, float32 [m, NaN unknown] for 32FC1. Formats: '<16UC1|32FC1>; compressedDepth [png|rvl]'. "
      "expected_shape (height, width) refuses other sizes. Raises ValueError naming what is wrong with the payload.");
  m.def(
      "encode_compressed_depth",
      [](const py::object& depth, const std::string& codec, double depth_max, double depth_quantization,
         int png_level) {
        if (py::isinstance<py::array>(depth))
        {
          py::dtype dt = py::reinterpret_borrow<py::array>(depth).dtype();
          if (cvTypeOf(dt) != CV_16UC1 && cvTypeOf(dt) != CV_32FC1)
            throw py::type_error("depth: dtype " + std::string(py::str(dt)) + ": expected uint16 (mm) or float32 (m)");
        }
        py::object keep;
        const cv::Mat m = asMat(depth, "depth", keep);
        CompressedDepthOptions o;
        o.codec = depthCodecFromString(codec);
        o.depth_max = depth_max;
        o.depth_quantization = depth_quantization;
        o.png_level = png_level;
        CompressedDepth c;
        {
          py::gil_scoped_release release;
          c = encodeCompressedDepth(m, o);
        }
        return py::make_tuple(c.format, py::bytes(reinterpret_cast<const char*>(c.data.data()), c.data.size()));
      },
      py::arg("depth"), py::arg("codec") = toString(cd_defaults.codec), py::arg("depth_max") = cd_defaults.depth_max,
      py::arg("depth_quantization") = cd_defaults.depth_quantization, py::arg("png_level") = cd_defaults.png_level,
      "(format, data) of a compressedDepth CompressedImage, as compressed_depth_image_transport writes it: a "
      "uint16 [mm] or float32 [m] image, codec 'png' or 'rvl'; pixels beyond depth_max [m] become 0 (unknown); "
      "float32 is stored as 16-bit inverse depth with depthQuantA = z0 (z0 + 1), z0 = depth_quantization.");
  m.def(
      "colour_labels",
      [](const py::object& depth, const py::object& labels, double max_depth) {
        py::object keep_d, keep_l;
        cv::Mat d = asMat(depth, "depth", keep_d);
        cv::Mat l = asMat(labels, "labels", keep_l);
        cv::Mat rgb;
        colourLabels(d, l, max_depth, rgb);
        py::array_t<std::uint8_t> out({rgb.rows, rgb.cols, 3});
        for (int r = 0; r < rgb.rows; ++r)
          std::memcpy(out.mutable_data(r, 0, 0), rgb.ptr(r), static_cast<std::size_t>(rgb.cols) * 3);
        return out;
      },
      py::arg("depth"), py::arg("labels"), py::arg("max_depth") = 12.0,
      "RGB picture of the labels over the depth (as the ROS debug image): kept grey by depth, floor green, "
      "above the ceiling plane blue, below the floor magenta, invalid black.");
  m.def(
      "morph_open",
      [](const py::object& img, int ksize, const std::string& shape) {
        py::object keep;
        cv::Mat m = asMat(img, "image", keep);
        cv::Mat out, scratch;
        morphOpen(m, out, ksize, kernelShapeFromString(shape), scratch);
        return matToArray(out);
      },
      py::arg("image"), py::arg("ksize"), py::arg("shape") = "rect", "The pipeline's morphological opening.");
}
