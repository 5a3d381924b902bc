// The binding's areas (src/python/bind_*.cpp), each adding its classes and functions to kinect_pipeline._core.
// module.cpp calls them in this order: a class is bound before the functions whose signatures name it.
#pragma once

#include <pybind11/pybind11.h>

namespace kinect_pipeline::python
{
/** Config (every field from model/config_table.h), CONFIG_FIELDS, the threshold curve and the sensor presets. */
void bindConfig(pybind11::module_& m);
/** Camera, SensorPose, PoseCorrection, FloorFit, Result, Pipeline, LABELS and the pose / tf functions. */
void bindPipeline(pybind11::module_& m);
/** Depth images and camera intrinsics as messages carry them; encode_depth; compressedDepth. */
void bindCodecs(pybind11::module_& m);
/** The offline tools: synthetic scenes and sensor noise, calibration, pictures, the baseline scan, morph_open. */
void bindSimulation(pybind11::module_& m);
}  // namespace kinect_pipeline::python
