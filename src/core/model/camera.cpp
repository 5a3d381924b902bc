#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/types.h"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace kinect_pipeline
{
namespace
{
constexpr double kMinFocal = 1e-2, kMaxFocal = 1e6;  // [px]
constexpr double kMaxPrincipal = 1e6;                // [px]

void requirePositiveSize(const char* name, int v)
{
  // The upper bound keeps a corrupt camera_info (a width of 2^29) from making the pipeline allocate gigabytes
  // for its per-column terms (found by fuzzing, test/fuzz).
  if (v < 1 || v > kMaxImageSide)
  {
    std::ostringstream s;
    s << "Camera." << name << " = " << v << ": expected an image size of 1 to " << kMaxImageSide << " pixels";
    throw std::invalid_argument(s.str());
  }
}
}  // namespace

Camera::Camera(int w, int h, double fx_, double fy_, double cx_, double cy_)
  : width(w), height(h), fx(fx_), fy(fy_), cx(cx_), cy(cy_)
{
  validate();
}

Camera Camera::fromFov(int width, int height, double hfov, double vfov)
{
  requirePositiveSize("width", width);
  requirePositiveSize("height", height);
  for (auto [name, v] : {std::pair<const char*, double>{"hfov", hfov}, {"vfov", vfov}})
  {
    if (!(v > 0.0 && v < kPi))
    {
      std::ostringstream s;
      s << "Camera.from_fov: " << name << " = " << v << " rad: expected a field of view in (0, pi) rad";
      throw std::invalid_argument(s.str());
    }
  }
  // Edge to edge: the outer pixel edges lie at -0.5 and width - 0.5 around the centre (width - 1) / 2.
  try
  {
    return Camera(width, height, 0.5 * width / std::tan(0.5 * hfov), 0.5 * height / std::tan(0.5 * vfov),
                  0.5 * (width - 1), 0.5 * (height - 1));
  }
  catch (const std::invalid_argument& e)  // a focal length out of range: say which field of view gave it
  {
    std::ostringstream s;
    s << "Camera.from_fov: hfov = " << hfov << ", vfov = " << vfov << " rad over " << width << "x" << height
      << " px: " << e.what();
    throw std::invalid_argument(s.str());
  }
}

double Camera::hfov() const
{
  return std::atan((cx + 0.5) / fx) + std::atan((width - 0.5 - cx) / fx);
}

double Camera::vfov() const
{
  return std::atan((cy + 0.5) / fy) + std::atan((height - 0.5 - cy) / fy);
}

void Camera::validate() const
{
  requirePositiveSize("width", width);
  requirePositiveSize("height", height);
  for (auto [name, v] : {std::pair<const char*, double>{"fx", fx}, {"fy", fy}})
  {
    if (!(std::isfinite(v) && v > 0.0))
    {
      std::ostringstream s;
      s << "Camera." << name << " = " << v
        << ": expected a finite focal length > 0 px (a camera_info with K = 0 is uncalibrated)";
      throw std::invalid_argument(s.str());
    }
    // Beyond these the field of view or the rays' slopes leave float range (found by fuzzing, test/fuzz).
    if (v < kMinFocal || v > kMaxFocal)
    {
      std::ostringstream s;
      s << "Camera." << name << " = " << v << ": expected a focal length of " << kMinFocal << " to " << kMaxFocal
        << " px";
      throw std::invalid_argument(s.str());
    }
  }
  for (auto [name, v] : {std::pair<const char*, double>{"cx", cx}, {"cy", cy}})
  {
    if (!(std::isfinite(v) && std::fabs(v) <= kMaxPrincipal))
    {
      std::ostringstream s;
      s << "Camera." << name << " = " << v << ": expected a finite principal point within +-" << kMaxPrincipal
        << " px";
      throw std::invalid_argument(s.str());
    }
  }
}

std::string Camera::describe() const
{
  std::ostringstream s;
  s << width << "x" << height << " fx=" << fx << " fy=" << fy << " cx=" << cx << " cy=" << cy;
  return s.str();
}

}  // namespace kinect_pipeline
