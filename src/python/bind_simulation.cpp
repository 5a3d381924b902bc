// Binding of the offline tools: synthetic scenes and sensor noise (synthetic.h), calibration from the floor
// (calibration.h), the debug picture (visualize.h), the baseline scan, and the pipeline's opening on its own. The
// tools (kinect_pipeline.scenes, bag, quality, calibrate, demo) and the tests use them; the node does not.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "arrays.h"
#include "bind.h"
#include "kinect_pipeline/io/visualize.h"
#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/config.h"
#include "kinect_pipeline/stages/opening_kernels.h"
#include "kinect_pipeline/tools/calibration.h"
#include "kinect_pipeline/tools/synthetic.h"

namespace kinect_pipeline::python
{
namespace
{

using BoxTuple = std::array<double, 6>;   // (x0, x1, y0, y1, z0, z1) [m]
using HoleTuple = std::array<double, 4>;  // (x0, x1, y0, y1) [m]

std::vector<Box> boxesOf(const std::vector<BoxTuple>& boxes)
{
  std::vector<Box> out;
  for (const auto& b : boxes)
    out.push_back({b[0], b[1], b[2], b[3], b[4], b[5]});
  return out;
}

py::dict renderingDict(const Rendering& r)
{
  py::dict d;
  d["depth"] = matToArray(r.depth);
  d["height"] = matToArray(r.height);
  d["range"] = matToArray(r.range);
  d["angle"] = matToArray(r.angle);
  d["object"] = matToArray(r.object);
  return d;
}

void bindScenes(py::module_& m)
{
  m.def(
      "render_scene",
      [](const Camera& cam, double height, double pitch, double roll, const std::vector<BoxTuple>& boxes,
         const std::vector<HoleTuple>& holes, double hole_depth, double ceiling, bool floor) {
        Scene s;
        s.floor = floor;
        s.boxes = boxesOf(boxes);
        for (const auto& h : holes)
          s.holes.push_back({h[0], h[1], h[2], h[3], 0.0, 0.0});
        s.hole_depth = hole_depth;
        s.ceiling = ceiling;
        Rendering r;
        {
          py::gil_scoped_release release;
          renderScene(cam, height, pitch, roll, s, r);
        }
        return renderingDict(r);
      },
      py::arg("camera"), py::arg("height"), py::arg("pitch"), py::arg("roll"), py::arg("boxes") = std::vector<BoxTuple>{},
      py::arg("holes") = std::vector<HoleTuple>{}, py::arg("hole_depth") = 0.5, py::arg("ceiling") = 0.0,
      py::arg("floor").noconvert() = true,
      "Ray-cast a scene (boxes (x0, x1, y0, y1, z0, z1) and hole footprints (x0, x1, y0, y1) in the gravity-aligned "
      "frame on the floor under the sensor). Returns dict of depth [m, +Inf none], height [m], range [m], angle [rad], "
      "object (-1 none, 0 floor, 1 ceiling, 2 hole, 10+i box i).");
  m.def(
      "render_lidar",
      [](const std::vector<BoxTuple>& boxes, double z, double angle_min, double increment, int beams, double range_max) {
        Scene s;
        s.boxes = boxesOf(boxes);
        return vecToArray(renderLidar(s, z, angle_min, increment, beams, range_max));
      },
      py::arg("boxes"), py::arg("z"), py::arg("angle_min"), py::arg("increment"), py::arg("beams"),
      py::arg("range_max") = 30.0,
      "Ranges of a level planar LiDAR at height z seeing the boxes (+Inf: nothing within range_max).");
}

void bindNoise(py::module_& m)
{
  m.def(
      "add_kinect_noise",
      [](const py::object& depth, std::uint64_t seed, double sigma0, double k, double dropout) {
        py::array_t<float> out = copyOf(metresImage(depth, "depth"));
        cv::Mat m(static_cast<int>(out.shape(0)), static_cast<int>(out.shape(1)), CV_32FC1, out.mutable_data());
        addKinectNoise(m, seed, sigma0, k, dropout);
        return out;
      },
      py::arg("depth"), py::arg("seed"), py::arg("sigma0") = 0.0015, py::arg("k") = 0.0019, py::arg("dropout") = 0.01,
      "Copy of a float32 depth [m] with Kinect-v2-like noise sigma0 + k (z - 0.4)^2 and dropouts (+Inf).");
  m.def(
      "add_tof_artefacts",
      [](const py::object& depth, std::uint64_t seed, double max_range, double flying, double edge_jump) {
        py::array_t<float> out = copyOf(metresImage(depth, "depth"));
        cv::Mat m(static_cast<int>(out.shape(0)), static_cast<int>(out.shape(1)), CV_32FC1, out.mutable_data());
        addTofArtefacts(m, seed, max_range, flying, edge_jump);
        return out;
      },
      py::arg("depth"), py::arg("seed"), py::arg("max_range") = 8.0, py::arg("flying") = 0.5,
      py::arg("edge_jump") = 0.3,
      "Copy of a float32 depth [m] with pixels beyond max_range unknown (+Inf) and flying pixels at depth jumps.");
  m.def(
      "add_stereo_artefacts",
      [](const py::object& depth, std::uint64_t seed, double focal_baseline, double subpixel, double bias,
         double speckle, int smear_rows, double smear_jump, double smear, double max_range, double dropout) {
        py::array_t<float> out = copyOf(metresImage(depth, "depth"));
        cv::Mat m(static_cast<int>(out.shape(0)), static_cast<int>(out.shape(1)), CV_32FC1, out.mutable_data());
        addStereoArtefacts(m, seed,
                           {focal_baseline, subpixel, bias, speckle, smear_rows, smear_jump, smear, max_range, dropout});
        return out;
      },
      py::arg("depth"), py::arg("seed"), py::arg("focal_baseline") = 617.0 * 0.05, py::arg("subpixel") = 0.08,
      py::arg("bias") = 0.12, py::arg("speckle") = 0.0002, py::arg("smear_rows") = 4, py::arg("smear_jump") = 0.15,
      py::arg("smear") = 0.2, py::arg("max_range") = 10.0, py::arg("dropout") = 0.01,
      "Copy of a float32 depth [m] with an active stereo camera's artefacts (RealSense-like): disparity noise "
      "(subpixel [px]) and offset (bias [px]), wrong matches in blobs (speckle), the matching window's smear "
      "(smear_rows above a pixel, smear_jump [m], probability smear), dropouts and nothing beyond max_range [m].");
  m.def(
      "stereo_sigma", py::vectorize([](double z) { return stereoSigma(z); }), py::arg("z"),
      "Depth noise of add_stereo_artefacts' defaults [m] at depth z [m]: z^2 subpixel / focal_baseline "
      "(numpy-vectorised).");
  m.def(
      "kinect_sigma", py::vectorize([](double z, double sigma0, double k) { return kinectSigma(z, sigma0, k); }),
      py::arg("z"), py::arg("sigma0") = 0.0015, py::arg("k") = 0.0019,
      "Depth noise of the Kinect v2 model [m] at depth z [m] (numpy-vectorised).");
}

py::dict floorPoseDict(const FloorPose& p)
{
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
}

void bindCalibration(py::module_& m)
{
  m.def(
      "calibrate_from_floor",
      [](const py::object& depth, const Camera& cam, double max_tilt, double min_fraction, double max_range,
         int iterations, int stride, std::uint64_t seed) {
        const FloatImage metres = metresImage(depth, "depth");
        const cv::Mat m = floatImage(metres);
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
        return floorPoseDict(p);
      },
      py::arg("depth"), py::arg("camera"), py::arg("max_tilt") = 0.7, py::arg("min_fraction") = 0.05,
      py::arg("max_range") = 6.0, py::arg("iterations") = 400, py::arg("stride") = 2, py::arg("seed") = 1,
      "Height, pitch, roll (and 1-sigma) of the sensor from the floor seen in a float32 depth frame [m].");
  m.def(
      "band_scan",
      [](const py::object& depth, const Camera& cam, int band_rows) {
        return vecToArray(bandScan(floatImage(metresImage(depth, "depth")), cam, band_rows));
      },
      py::arg("depth"), py::arg("camera"), py::arg("band_rows") = 1,
      "Baseline (depthimage_to_laserscan's way): nearest depth per column in a band of rows, no floor removal.");
}

void bindPictures(py::module_& m)
{
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
        for (int r = 0; m.type() == CV_32FC1 && r < m.rows; ++r)
          for (int u = 0; u < m.cols; ++u)
            if (std::isnan(m.ptr<float>(r)[u]))
              throw py::value_error("image: NaN at row " + std::to_string(r) + ", column " + std::to_string(u) +
                                    ": expected no NaN (the opening's order of NaN is undefined: map unknown "
                                    "pixels to +inf first, as the pipeline does)");
        cv::Mat out, scratch;
        morphOpen(m, out, ksize, kernelShapeFromString(shape), scratch);
        return matToArray(out);
      },
      py::arg("image"), py::arg("ksize"), py::arg("shape") = "rect", "The pipeline's morphological opening.");
}

}  // namespace

void bindSimulation(py::module_& m)
{
  bindScenes(m);
  bindNoise(m);
  bindCalibration(m);
  bindPictures(m);
}

}  // namespace kinect_pipeline::python
