// The binding's conversions between numpy arrays / bytes and the core's cv::Mat / vectors, shared by the
// src/python/bind_*.cpp files. Conversions and their type errors only: what is valid input is the core's to say.
#pragma once

#include <string>
#include <vector>

#include <opencv2/core.hpp>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include "kinect_pipeline/model/encoding.h"

namespace kinect_pipeline::python
{
namespace py = pybind11;

/** @return CV_8UC1, CV_16UC1 or CV_32FC1 for a uint8, uint16 or float32 dtype (by kind and size); else -1. */
int cvTypeOf(const py::dtype& dt);

/** @return the single-channel cv type of an encoding's images: CV_8UC1, CV_16UC1 or CV_32FC1. */
int cvTypeOf(Encoding e);

/** @return the name of @p obj's type, e.g. "list". */
std::string typeName(const py::handle& obj);

/**
 * A real number (int, float or a numpy scalar; not a str, None or a sequence) as a double.
 * @throw py::type_error "WHAT = 'abc' (str): expected a number"
 */
double numberOf(const py::handle& v, const std::string& what);

/**
 * True or False (a Python or numpy bool only).
 * @throw py::type_error "WHAT = None (NoneType): expected True or False"
 */
bool flagOf(const py::handle& v, const std::string& what);

/**
 * A 2-D uint8, uint16 or float32 numpy array as a cv::Mat. Zero-copy when rows are positive-strided and pixels
 * adjacent; otherwise a C-contiguous, native-order copy is made. Either way the array is kept alive in @p keep.
 * @param what the argument's name, quoted in errors
 * @param cv_type if given, receives the cv type
 * @throw py::type_error for something else than a numpy array or another dtype; py::value_error for another
 *        number of dimensions or an empty array
 */
cv::Mat asMat(const py::handle& obj, const char* what, py::object& keep, int* cv_type = nullptr);

/** @return a new numpy array with a copy of a CV_8UC1, CV_16UC1, CV_16SC1 or CV_32FC1 image. */
py::array matToArray(const cv::Mat& m);

/** @return a new 1-D float32 array with a copy of @p v. */
py::array_t<float> vecToArray(const std::vector<float>& v);

/**
 * A CompressedImage's data as bytes: bytes, bytearray, memoryview or a 1-D uint8 array (what rosbags gives),
 * kept alive in @p keep. @throw py::type_error naming @p what and what was expected
 */
py::buffer_info asBytes(const py::object& obj, const char* what, py::object& keep);

/** A float32 depth image [m] as the simulation tools take it (C order; no silent narrowing from float64). */
using FloatImage = py::array_t<float, py::array::c_style>;

/**
 * A depth image in metres as the simulation and calibration tools take it: a float32 array (a C-order copy where
 * needed) or a nested list of numbers. @throw py::type_error naming @p what and its dtype for an integer array
 * (sensor units, not metres: millimetres would be taken as metres) or a float64 one (no silent narrowing)
 */
FloatImage metresImage(const py::handle& obj, const char* what);

/** @return a cv::Mat over @p depth's pixels (no copy). @throw py::value_error unless it is 2-D */
cv::Mat floatImage(const FloatImage& depth);

/** @return a new 2-D float32 array with a copy of @p depth's pixels. @throw py::value_error unless it is 2-D */
py::array_t<float> copyOf(const FloatImage& depth);

}  // namespace kinect_pipeline::python
