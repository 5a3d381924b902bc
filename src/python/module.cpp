// pybind11 binding of the ROS-free core: kinect_pipeline._core. This file only gathers the areas (bind.h); each
// bind_*.cpp file binds, and what is policy lives in the core (or in the kinect_pipeline package).
#include <pybind11/pybind11.h>

#include "bind.h"

PYBIND11_MODULE(_core, m)
{
  namespace kp = kinect_pipeline::python;
  m.doc() = "ROS-free core of kinect_pipeline (C++/OpenMP). Use the kinect_pipeline package, not this module.";
  kp::bindConfig(m);
  kp::bindPipeline(m);
  kp::bindCodecs(m);
  kp::bindSimulation(m);
}
