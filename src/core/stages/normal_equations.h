// Private to the core: the floor fit's weighted normal equations (stages/floor_fit.cpp), a loop compiled once per
// SIMD target (stages/normal_equations.cpp).
#pragma once

namespace kinect_pipeline
{
namespace detail
{
/** The fit's sums run in this many independent lanes (one AVX-512 vector of floats). */
constexpr int kNormalLanes = 16;

/**
 * The weighted normal equations of the plane e = a + b x + c y over points [0, n) (n a multiple of kNormalLanes):
 * Tukey's biweight of each residual at scale window / inv_sigma, weight inv_sigma^2 on top; points farther than
 * sqrt(radius2) do not count. Sums per lane in
 * float (independent accumulators, so the lanes vectorise without reassociation), then in double.
 * @param out xx, xy, xz, yy, yz, zz of the matrix, then the right-hand side (3)
 */
void normalEquations(const float* x, const float* y, const float* e, const float* inv_sigma, const float* range2, int n,
                     float a, float b, float c, float inv_window, float radius2, double out[9]);
}  // namespace detail
}  // namespace kinect_pipeline
