// Binding of the per-frame pipeline and its results: Camera, the pose types, FloorFit, Result, Pipeline, LABELS,
// and the pose / tf functions the tools find a frame's pose with.
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <mutex>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "arrays.h"
#include "bind.h"
#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/model/pose.h"
#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/simd.h"

namespace kinect_pipeline::python
{
namespace
{

/** What process() returns; numpy arrays own their memory. */
struct PyResult
{
  py::array depth, labels;
  py::array_t<float> ranges, intensities, cliff_ranges;
  float angle_min, angle_max, angle_increment, range_min, range_max;
  py::dict counts, times;
  std::uint64_t speckles = 0;
  bool level_rows = false;
  SensorPose pose{0.0, 0.0, 0.0};
  FloorFitResult floor_fit;
  FrameResult frame;  ///< the core's result for describe(): no pixels, its depth a header over `depth`'s
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
  const double t = numberOf(stamp, "stamp");
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

/** Result.level_rows' docstring, with the core's tolerance (kRollSnap). */
const std::string& levelRowsDoc()
{
  static const std::string doc = [] {
    std::ostringstream s;
    s << "the pose had no roll (0 or +-pi, within " << kRollSnap << " rad): the level paths; else the roll paths, "
      << "about twice the time of an 8- or 16-bit frame";
    return s.str();
  }();
  return doc;
}

/** The core's frame result as Python data (fresh arrays and dicts). */
void toPython(FrameResult&& fr, PyResult& res)
{
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
  res.speckles = fr.speckles;
  res.level_rows = fr.level_rows;
  res.pose = fr.pose;
  res.floor_fit = fr.floor_fit;
  res.times["prepare"] = fr.times.prepare;
  res.times["floor_fit"] = fr.times.floor_fit;
  res.times["erode"] = fr.times.erode;
  res.times["classify_scan"] = fr.times.classify_scan;
  res.times["confidence"] = fr.times.confidence;
  res.times["total"] = fr.times.total;
  res.frame = std::move(fr);
}

/** One frame through @p call (a Pipeline::process), the GIL released; the core writes into fresh numpy arrays. */
template <typename F>
PyResult runFrame(PyPipeline& self, const py::object& depth, F&& call)
{
  py::object keep;
  cv::Mat in = asMat(depth, "depth", keep);
  PyResult res;
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
    fr.speckles = self.result.speckles;
    fr.level_rows = self.result.level_rows;
    fr.times = self.result.times;
    fr.pose = self.result.pose;
    fr.floor_fit = self.result.floor_fit;
    fr.depth = self.result.depth;  // a header over res.depth, which the result keeps alive
    if (self.result.depth.data != depth_out || self.result.labels.data != labels_out)
      throw std::logic_error("kinect_pipeline: the core reallocated its output");
  }
  toPython(std::move(fr), res);
  return res;
}

void bindCamera(py::module_& m)
{
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
}

void bindPoses(py::module_& m)
{
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
      .def("__getitem__",
           [](const PoseCorrection& c, int i) { return poseTerm(SensorPose{c.height, c.pitch, c.roll}, i); })
      .def("__iter__", [](const PoseCorrection& c) { return py::iter(py::make_tuple(c.height, c.pitch, c.roll)); })
      .def("__repr__",
           [](const PoseCorrection& c) { return describeTerms("PoseCorrection", c.height, c.pitch, c.roll); });
}

void bindFloorFit(py::module_& m)
{
  py::class_<FloorFitResult>(m, "FloorFit", "What the floor refinement decided for one frame.")
      .def_property_readonly("accepted", &FloorFitResult::accepted, "the frame was processed at the fitted pose")
      .def_property_readonly(
          "reason", [](const FloorFitResult& f) { return toString(f.status); },
          "'accepted', 'off', 'too few pixels', 'spread too large', 'out of bounds', 'ill-conditioned' or 'not better than the prior'")
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
      .def_readonly("std", &FloorFitResult::std,
                    "standard deviations of the fitted floor's terms: height [m], pitch and roll slopes [rad]")
      .def_property_readonly(
          "profile",
          [](const FloorFitResult& f) {
            py::list out;
            for (int k = 0; k < FloorProfileBands::kBands; ++k)
              out.append(py::make_tuple((k + 0.5) * FloorProfileBands::kBandWidth, f.profile.bias[k],
                                        f.profile.samples[k]));
            return out;
          },
          "the floor profile after this frame, per band of the plane's depth: (band centre [m], the learned depth of "
          "the floor beyond the plane's [m], this frame's floor samples in the band); all 0 while it is off")
      .def("__repr__", [](const FloorFitResult& f) {
        std::ostringstream s;
        s << "FloorFit(reason='" << toString(f.status) << "', pixels=" << f.pixels << ", support=" << f.support
          << ", candidates=" << f.candidates
          << ", correction=" << describeTerms("", f.applied.height, f.applied.pitch, f.applied.roll)
          << ", learned=" << describeTerms("", f.learned.height, f.learned.pitch, f.learned.roll) << ")";
        return s.str();
      });
}

void bindResult(py::module_& m)
{
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
      .def_readonly("speckles", &PyResult::speckles,
                    "speckle_jump: pixels taken as wrong matches (no measurement) before the opening")
      .def_readonly("level_rows", &PyResult::level_rows, levelRowsDoc().c_str())
      .def_readonly("times", &PyResult::times, "wall-clock ms per stage")
      .def_readonly("pose", &PyResult::pose, "the SensorPose the frame was processed at (the refined prior)")
      .def_readonly("floor_fit", &PyResult::floor_fit, "what the floor refinement decided (FloorFit)")
      .def("__repr__", [](const PyResult& r) { return describe(r.frame); });
  py::dict labels;  // the core's own list: Result.labels values by name
  for (int k = 0; k < kNumLabels; ++k)
    labels[kLabelNames[k]] = k;
  m.attr("LABELS") = labels;
  m.attr("MILLIMETRE_MEDIAN") = kMillimetreMedian;  // [m] the median depth above which metres are not metres
}

/** Predicted depth per pixel [m] of the floor or the ceiling plane at the last frame's pose. */
py::array_t<double> predicted(PyPipeline& self, bool floor)
{
  std::lock_guard<std::mutex> lock(self.mutex);
  const PlaneModel& p = self.pipe.planes();
  const Camera& c = self.pipe.camera();
  // The planes exist from a frame's pose on: none yet (a new pipeline, a refused frame, a new config) read past
  // the terms' ends.
  const auto size = [](int n) { return static_cast<std::size_t>(n); };
  if (p.colTerm().size() != size(c.width) || p.rowTerm().size() != size(c.height))
    throw std::runtime_error(std::string(floor ? "predicted_floor" : "predicted_ceiling") +
                             "(): no planes yet: they are those of the last frame's pose, and no frame was processed "
                             "since the pipeline was made or its config set: expected process() first");
  py::array_t<double> out({c.height, c.width});
  auto o = out.mutable_unchecked<2>();
  for (int r = 0; r < c.height; ++r)
    for (int u = 0; u < c.width; ++u)
      o(r, u) = floor ? p.floorDepth(u, r) : p.ceilingDepth(u, r);
  return out;
}

py::object finiteOrNone(double v) { return std::isfinite(v) ? py::cast(v) : py::none(); }

/** Element i of a floor_state tuple as a number (None: NaN where @p none_ok). */
double stateItem(const py::tuple& t, std::size_t i, bool none_ok = false)
{
  if (none_ok && t[i].is_none())
    return std::numeric_limits<double>::quiet_NaN();
  return numberOf(t[i], "floor_state[" + std::to_string(i) + "]");
}

constexpr std::size_t kProfileBands = FloorProfileBands::kBands;
constexpr std::size_t kFullState = 8 + 2 * kProfileBands;

py::tuple floorState(PyPipeline& self)
{
  const FloorFit::State s = self.pipe.floorFit().state();
  py::list out;
  for (const double v : {s.learned.height, s.learned.pitch, s.learned.roll})
    out.append(v);
  for (const double v : {s.last_stamp, s.weight.height, s.weight.pitch, s.weight.roll})
    out.append(finiteOrNone(v));
  for (std::size_t k = 0; k < kProfileBands; ++k)
    out.append(static_cast<double>(s.profile.bias[k]));
  for (std::size_t k = 0; k < kProfileBands; ++k)
    out.append(static_cast<double>(s.profile.weight[k]));
  out.append(s.profile.since_learned);
  return py::tuple(out);
}

void setFloorState(PyPipeline& self, const py::tuple& t)
{
  if (t.size() != 4 && t.size() != 7 && t.size() != kFullState)
    throw py::value_error("floor_state: expected (height, pitch, roll, last_stamp or None[, the learned correction's "
                          "weight of height, pitch, roll or None[, the floor profile's " +
                          std::to_string(kProfileBands) + " biases, " + std::to_string(kProfileBands) +
                          " weights and the time since it learned]]), got " + std::string(py::repr(t)));
  FloorFit::State s;
  s.learned = {stateItem(t, 0), stateItem(t, 1), stateItem(t, 2)};
  s.last_stamp = stateItem(t, 3, true);
  if (t.size() >= 7)
    s.weight = {stateItem(t, 4, true), stateItem(t, 5, true), stateItem(t, 6, true)};
  s.profile = FloorProfile().bands();
  if (t.size() == kFullState)
    for (std::size_t k = 0; k < kProfileBands; ++k)
    {
      s.profile.bias[k] = static_cast<float>(stateItem(t, 7 + k));
      s.profile.weight[k] = static_cast<float>(stateItem(t, 7 + kProfileBands + k));
      s.profile.since_learned = stateItem(t, 7 + 2 * kProfileBands);
    }
  std::lock_guard<std::mutex> lock(self.mutex);
  self.pipe.restoreFloorFit(s);
}

void bindPipelineClass(py::module_& m)
{
  py::class_<PyPipeline>(m, "Pipeline", "The per-frame processing. Keeps each beam's confidence history.")
      .def(py::init<const Camera&, const Config&, bool>(), py::arg("camera"), py::arg("config"),
           py::arg("reference_paths").noconvert() = false,
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
      .def(
          "reset", [](PyPipeline& self) { self.pipe.reset(); },
          "Forget the confidence history and the floor refinement's learned correction.")
      .def_property_readonly(
          "learned_correction", [](PyPipeline& self) { return self.pipe.floorFit().learned(); },
          "The floor refinement's learned correction now (PoseCorrection).")
      .def_property("floor_state", &floorState, &setFloorState,
                    "What the floor refinement carries between frames: (learned height [m], pitch, roll [rad], the "
                    "last frame's stamp [s] or None, the learned correction's weight per term or None, the floor "
                    "profile's bias [m] and weight per band and the time since it learned [s]); set it to continue another run exactly (a resumed "
                    "replay).")
      .def_property(
          "config", [](PyPipeline& self) { return self.pipe.config(); },
          [](PyPipeline& self, const Config& c) {
            std::lock_guard<std::mutex> lock(self.mutex);
            self.pipe.setConfig(c);
          })
      .def_property_readonly("camera", [](PyPipeline& self) { return self.pipe.camera(); })
      .def(
          "predicted_floor", [](PyPipeline& self) { return predicted(self, true); },
          "Predicted floor depth per pixel [m] (+Inf: the ray never meets it) at the last frame's pose.")
      .def(
          "predicted_ceiling", [](PyPipeline& self) { return predicted(self, false); },
          "Predicted ceiling-plane depth per pixel [m] (+Inf: never met) at the last frame's pose.");
}

void bindTransforms(py::module_& m)
{
  using Tf = std::pair<std::array<double, 4>, std::array<double, 3>>;  // ((qx, qy, qz, qw), (x, y, z))
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
      "interpolate_transform",
      [=](const Tf& a, const Tf& b, double f) { return fromRigid(interpolate(toRigid(a), toRigid(b), f)); },
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
  m.def("wrap_angle", &wrapAngle, py::arg("a"), "The angle a [rad] turned by whole turns into [-pi, pi].");
}

void bindSimd(py::module_& m)
{
  m.def("simd_targets", &simdTargets,
        "The SIMD targets of the kernels this CPU can run, best first: avx512, avx2, sse4, scalar (aarch64: "
        "sve2_128 on CPUs of 128-bit SVE2 vectors, sve2, sve, neon, scalar). Every one gives the same bits.");
  m.def("simd_target", &simdTarget, "The SIMD target the kernels run now.");
  m.def("restrict_simd", &restrictSimd, py::arg("target"),
        "Restricts the kernels to one target for the whole process ('native': the best the CPU has). ValueError "
        "for a target this CPU lacks. The environment variable KINECT_PIPELINE_SIMD does the same.");
}
}  // namespace

void bindPipeline(py::module_& m)
{
  bindCamera(m);
  bindPoses(m);
  bindFloorFit(m);
  bindResult(m);
  bindPipelineClass(m);
  bindTransforms(m);
  bindSimd(m);
}

}  // namespace kinect_pipeline::python
