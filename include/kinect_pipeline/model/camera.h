/**
 * @file camera.h
 * @brief Pinhole model of the depth camera (no distortion: depth drivers publish rectified depth).
 */
#pragma once

#include <string>

namespace kinect_pipeline
{

/**
 * Pinhole camera model in pixel units, optical frame (x right, y down, z forward; REP 103 "_optical").
 *
 * Pixel (u, v) with integer centres sees the ray direction ((u - cx) / fx, (v - cy) / fy, 1).
 */
/** Largest image width or height a Camera accepts [px] (depth cameras have a few hundred to a few thousand). */
constexpr int kMaxImageSide = 16384;

struct Camera
{
  int width = 0;    ///< image width [px]
  int height = 0;   ///< image height [px]
  double fx = 0.0;  ///< focal length along x [px]
  double fy = 0.0;  ///< focal length along y [px]
  double cx = 0.0;  ///< principal point x [px]
  double cy = 0.0;  ///< principal point y [px]

  Camera() = default;

  /**
   * @brief Camera from intrinsics.
   * @throw std::invalid_argument if any value is out of range (see validate()).
   */
  Camera(int width, int height, double fx, double fy, double cx, double cy);

  /**
   * @brief Camera for users who only know the fields of view (the thesis: 512x424, 70.6 x 60 deg).
   * @param hfov horizontal field of view [rad], edge to edge, in (0, pi)
   * @param vfov vertical field of view [rad], edge to edge, in (0, pi)
   * @return a camera with its principal point in the image centre ((w-1)/2, (h-1)/2).
   * @throw std::invalid_argument for a size <= 0 or a field of view outside (0, pi).
   */
  static Camera fromFov(int width, int height, double hfov, double vfov);

  /** @return the horizontal field of view [rad], edge to edge. */
  double hfov() const;
  /** @return the vertical field of view [rad], edge to edge. */
  double vfov() const;

  /**
   * @brief Checks the model.
   * @throw std::invalid_argument naming the field, its value and what was expected
   *        (width/height in 1..kMaxImageSide, fx/fy in 0.01..1e6 px, |cx|, |cy| <= 1e6 px).
   */
  void validate() const;

  /** @return a one-line description, e.g. "512x424 fx=365.5 fy=365.5 cx=255.5 cy=211.5". */
  std::string describe() const;

  bool operator==(const Camera& o) const
  {
    return width == o.width && height == o.height && fx == o.fx && fy == o.fy && cx == o.cx && cy == o.cy;
  }
  bool operator!=(const Camera& o) const { return !(*this == o); }
};

}  // namespace kinect_pipeline
