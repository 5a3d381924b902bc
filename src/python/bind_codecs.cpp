// Binding of the codecs: depth images and camera intrinsics as messages carry them (depth_image.h), float metres
// in an encoding (encode_depth), and compressedDepth (compressed_depth.h).
#include <algorithm>
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include "arrays.h"
#include "bind.h"
#include "kinect_pipeline/io/compressed_depth.h"
#include "kinect_pipeline/io/depth_image.h"
#include "kinect_pipeline/io/rectify.h"
#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/tools/synthetic.h"

namespace kinect_pipeline::python
{
namespace
{
// A row-major 3x3 matrix from any sequence of 9 numbers.
std::array<double, 9> matrix9(const py::object& K)
{
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
  return k;
}

void bindMessages(py::module_& m)
{
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
      "rectified_intrinsics",
      [](const std::vector<double>& P) -> std::optional<std::array<double, 9>> {
        if (P.size() != 12)
          throw py::value_error("P: expected 12 values (row-major 3x4), got " + std::to_string(P.size()));
        std::array<double, 12> p{};
        std::copy(P.begin(), P.end(), p.begin());
        return rectifiedIntrinsics(p);
      },
      py::arg("P"),
      "A rectified image's K from a sensor_msgs/CameraInfo's P (its left 3x3), as image_geometry takes it; None "
      "where P is not set (P[0] = 0) or not of the form [fx 0 cx Tx; 0 fy cy Ty; 0 0 1 0].");
  m.def(
      "camera_from_intrinsics",
      [](std::uint32_t width, std::uint32_t height, const py::object& K, const std::string& frame_id,
         std::uint32_t binning_x, std::uint32_t binning_y, const std::array<std::uint32_t, 4>& roi) {
        const ImageWindow window{binning_x, binning_y, roi[0], roi[1], roi[2], roi[3]};
        return cameraFromIntrinsics(width, height, matrix9(K), frame_id, window);
      },
      py::arg("width"), py::arg("height"), py::arg("K"), py::arg("frame_id") = "", py::arg("binning_x") = 0,
      py::arg("binning_y") = 0, py::arg("roi") = std::array<std::uint32_t, 4>{0, 0, 0, 0},
      "The camera of the images a sensor_msgs/CameraInfo goes with: its width, height and K (fx = K[0], fy = K[4], "
      "cx = K[2], cy = K[5]) at full resolution, taken down to its binning and roi (x_offset, y_offset, width, "
      "height; all 0: the whole image) as REP 104 and image_geometry read them. ValueError for K[0] = 0 (an "
      "uncalibrated camera), a zero size, non-finite values, a K not of the form [fx s cx; 0 fy cy; 0 0 1], a skew s "
      "that would move a pixel by a pixel or more, or an roi outside the image (the ROS node's checks).");
}

void bindRectifier(py::module_& m)
{
  py::class_<DepthRectifier>(m, "DepthRectifier",
                             "A raw depth image to the rectified one of the same camera matrix, by a "
                             "sensor_msgs/CameraInfo's distortion_model and D (io/rectify.h): each pixel the raw "
                             "pixel nearest to where its ray meets the raw image (depth is never blended), 0 where "
                             "that lies outside it.")
      .def(py::init<const Camera&, const std::string&, const std::vector<double>&>(), py::arg("camera"),
           py::arg("distortion_model"), py::arg("D"),
           "camera: the image's (its binning and roi applied); distortion_model 'plumb_bob' (D: k1 k2 p1 p2 [k3]), "
           "'rational_polynomial' (8) or 'equidistant' (4); any model with D all 0 is no distortion. ValueError "
           "for another model or length, naming them.")
      .def_property_readonly("identity", &DepthRectifier::identity, "No distortion: apply() copies.")
      .def_property_readonly("max_shift", &DepthRectifier::maxShift, "The farthest any pixel moves [px].")
      .def_property_readonly("outside", &DepthRectifier::outside,
                             "The fraction of the rectified image whose rays meet the raw image outside it.")
      .def(
          "apply",
          [](const DepthRectifier& r, const py::object& depth) {
            py::object keep;
            const cv::Mat raw = asMat(depth, "depth", keep);
            cv::Mat out;
            r.apply(raw, out);
            return matToArray(out);
          },
          py::arg("depth"), "The rectified image of a raw depth image (uint8, uint16 or float32) as a new array.");
  py::class_<TopicRectification>(m, "TopicRectification",
                                 "The rectification of one topic's frames, as the node and the bag tools do it: "
                                 "decided anew, and its maps built, only where the mode, camera or distortion "
                                 "changed.")
      .def(py::init<>())
      .def(
          "apply",
          [](TopicRectification& r, const std::string& mode, const std::string& topic, const Camera& camera,
             const std::string& model, const std::vector<double>& D, const py::object& depth,
             const std::optional<std::vector<double>>& R) {
            py::object keep;
            const cv::Mat raw = asMat(depth, "depth", keep);
            CameraLens lens{model, D, {}};
            if (R && !R->empty())
            {
              if (R->size() != 9)
                throw py::value_error("R: expected 9 values (row-major 3x3), got " + std::to_string(R->size()));
              std::copy(R->begin(), R->end(), lens.R.begin());
            }
            const cv::Mat& out = r.apply(mode, topic, camera, lens, raw);
            return out.data == raw.data ? py::object(depth) : py::object(matToArray(out));
          },
          py::arg("mode"), py::arg("image_topic"), py::arg("camera"), py::arg("distortion_model"), py::arg("D"),
          py::arg("depth"), py::arg("R") = py::none(),
          "The image to process: depth itself, or its rectified image (a new array). R: the camera_info's (a "
          "rotation other than the identity is a stereo camera's, whose depth images auto takes as rectified). "
          "ValueError for a bad mode or a distortion it would need and cannot take.")
      .def_property_readonly("why", &TopicRectification::why, "What decided the last frame's rectification.")
      .def_property_readonly("rectifies", &TopicRectification::rectifies,
                             "The last apply() rectified the image (else it is taken as rectified already).")
      .def_property_readonly("distorts", &TopicRectification::distorts,
                             "The last frame's camera has a lens distortion the mode looked at (not with 'never').");
  m.def(
      "rectify_wanted",
      [](const std::string& mode, const std::string& image_topic, const DepthRectifier& r, bool stereo) {
        std::string why;
        const bool yes = rectifyWanted(mode, image_topic, r, stereo, why);
        return py::make_tuple(yes, why);
      },
      py::arg("mode"), py::arg("image_topic"), py::arg("rectifier"), py::arg("stereo") = false,
      "(whether, why): the images on image_topic are rectified before the pipeline, by mode 'always', 'never' or "
      "'auto' (unless the topic's last name holds 'rect', as ROS names rectified images, or stereo: the camera_info's R "
      "rotates); the node's rule.");
}

void bindEncodeDepth(py::module_& m)
{
  m.def(
      "encode_depth",
      [](const py::object& metres, const std::string& encoding, double max_depth) {
        py::object keep;
        int type = 0;
        cv::Mat m = asMat(metres, "metres", keep, &type);
        if (type != CV_32FC1)
          throw py::type_error("metres: expected a float32 array");
        return matToArray(encodeDepth(m, cvTypeOf(encodingFromString(encoding)), max_depth));
      },
      py::arg("metres"), py::arg("encoding"), py::arg("max_depth") = 12.0,
      "Float metres -> 8UC1 normalised / 16UC1 mm / 32FC1 (unknown -> 0, NaN kept for float).");
}

/** decode_compressed_depth's expected_shape (height, width) as a size; None: any size. */
cv::Size expectedSize(const std::optional<std::pair<int, int>>& expected_shape)
{
  if (!expected_shape)
    return cv::Size();
  const auto [h, w] = *expected_shape;
  if (h < 1 || w < 1)
    throw py::value_error("expected_shape = (" + std::to_string(h) + ", " + std::to_string(w) +
                          "): expected (height, width) of at least one pixel each, or None");
  return cv::Size(w, h);
}

void bindCompressedDepth(py::module_& m)
{
  m.def(
      "decode_compressed_depth",
      [](const py::object& format, const py::object& data, std::optional<std::pair<int, int>> expected_shape) {
        if (!py::isinstance<py::str>(format))
          throw py::type_error("format: " + typeName(format) + ": expected a str such as '16UC1; compressedDepth png'");
        const std::string f = format.cast<std::string>();
        const cv::Size expected = expectedSize(expected_shape);
        py::object keep;
        const py::buffer_info bytes = asBytes(data, "data", keep);
        cv::Mat depth;
        {
          py::gil_scoped_release release;
          depth = decodeDepthImage(f, static_cast<const std::uint8_t*>(bytes.ptr), static_cast<std::size_t>(bytes.size),
                                   expected);
        }
        return matToArray(depth);
      },
      py::arg("format"), py::arg("data"), py::arg("expected_shape") = py::none(),
      "A depth CompressedImage (its format and data: bytes or a uint8 array) as a depth image: uint16 [mm, 0 "
      "unknown] for 16UC1, float32 [m, NaN unknown] for 32FC1. Formats: '<16UC1|32FC1>; compressedDepth [png|rvl]' "
      "and image_transport's compressed PNG of 16-bit depth, '<16UC1|mono16>; png compressed'. expected_shape "
      "(height, width) refuses other sizes. Raises ValueError naming what is wrong with the format or the payload.");
  const CompressedDepthOptions defaults;
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
      py::arg("depth"), py::arg("codec") = toString(defaults.codec), py::arg("depth_max") = defaults.depth_max,
      py::arg("depth_quantization") = defaults.depth_quantization, py::arg("png_level") = defaults.png_level,
      "(format, data) of a compressedDepth CompressedImage, as compressed_depth_image_transport writes it: a "
      "uint16 [mm] or float32 [m] image, codec 'png' or 'rvl'; pixels beyond depth_max [m] become 0 (unknown); "
      "float32 is stored as 16-bit inverse depth with depthQuantA = z0 (z0 + 1), z0 = depth_quantization.");
}

}  // namespace

void bindCodecs(py::module_& m)
{
  bindMessages(m);
  bindRectifier(m);
  bindEncodeDepth(m);
  bindCompressedDepth(m);
}

}  // namespace kinect_pipeline::python
