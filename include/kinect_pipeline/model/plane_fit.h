/**
 * @file plane_fit.h
 * @brief The weighted least-squares plane z = a + b x + c y: the one plane fitter of the per-frame floor fit
 *        (robust weights and a prior per term, sums in vector lanes) and of the offline floor calibration.
 *
 * Both fit in the gravity-aligned frame of a pose (levelFromOptical, pose.h), where the floor is nearly z = const:
 * there the vertical residual is the distance from the plane to first order.
 */
#pragma once

namespace kinect_pipeline
{

/** The normal equations of the plane z = a + b x + c y: sums over the points, each with its weight w. */
struct PlaneSums
{
  /// the symmetric matrix over (1, x, y), upper triangle: sum w, w x, w y, w x x, w x y, w y y
  double m[6] = {};
  /// the right-hand side: sum w z, w z x, w z y
  double rhs[3] = {};
  void add(double x, double y, double z, double w)
  {
    m[0] += w;
    m[1] += w * x;
    m[2] += w * y;
    m[3] += w * x * x;
    m[4] += w * x * y;
    m[5] += w * y * y;
    rhs[0] += w * z;
    rhs[1] += w * z * x;
    rhs[2] += w * z * y;
  }
};

/**
 * @brief Solves the normal equations n x = g (n: upper triangle as PlaneSums::m, a prior may be added to its
 *        diagonal) for x = (a, b, c).
 * @return false (x unchanged) where n is singular or not finite.
 */
bool solvePlane(const double n[6], const double g[3], double x[3]);

/** @brief The diagonal of n's inverse: each term's variance per unit of the residuals' variance (+Inf where n is
 *         singular). */
void planeTermVariances(const double n[6], double out[3]);

}  // namespace kinect_pipeline
