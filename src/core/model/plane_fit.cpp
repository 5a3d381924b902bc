// The weighted least-squares plane z = a + b x + c y (plane_fit.h): the floor fit's and the calibration's.
#include "kinect_pipeline/model/plane_fit.h"

#include <cmath>
#include <limits>

namespace kinect_pipeline
{

bool solvePlane(const double n[6], const double g[3], double x[3])
{
  // n: xx, xy, xz, yy, yz, zz
  const double a = n[0], b = n[1], c = n[2], d = n[3], e = n[4], f = n[5];
  const double c00 = d * f - e * e, c01 = c * e - b * f, c02 = b * e - c * d;
  const double det = a * c00 + b * c01 + c * c02;
  if (!(std::fabs(det) > 0.0) || !std::isfinite(det))
    return false;
  const double c11 = a * f - c * c, c12 = b * c - a * e, c22 = a * d - b * b;
  x[0] = (c00 * g[0] + c01 * g[1] + c02 * g[2]) / det;
  x[1] = (c01 * g[0] + c11 * g[1] + c12 * g[2]) / det;
  x[2] = (c02 * g[0] + c12 * g[1] + c22 * g[2]) / det;
  return true;
}

void planeTermVariances(const double n[6], double out[3])
{
  const double a = n[0], b = n[1], c = n[2], d = n[3], e = n[4], f = n[5];
  const double c00 = d * f - e * e, c01 = c * e - b * f, c02 = b * e - c * d;
  const double det = a * c00 + b * c01 + c * c02;
  const double inf = std::numeric_limits<double>::infinity();
  if (!(det > 0.0) || !std::isfinite(det))
  {
    out[0] = out[1] = out[2] = inf;
    return;
  }
  out[0] = c00 / det;
  out[1] = (a * f - c * c) / det;
  out[2] = (a * d - b * b) / det;
}

}  // namespace kinect_pipeline
