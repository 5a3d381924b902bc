// The floor fit's weighted normal equations (stages/normal_equations.h), compiled once per SIMD target.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "stages/normal_equations.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "stages/normal_equations.h"

#include <algorithm>

#include "stages/frame_common.h"

HWY_BEFORE_NAMESPACE();
namespace kinect_pipeline
{
namespace detail
{
namespace HWY_NAMESPACE
{
void normalEquationsOf(const float* __restrict x, const float* __restrict y, const float* __restrict e,
                       const float* __restrict inv_sigma, const float* __restrict range2, int n, float a, float b,
                       float c, float inv_window, float radius2, double* out)
{
  float acc[9][kNormalLanes] = {};
  for (int i = 0; i < n; i += kNormalLanes)
    for (int j = 0; j < kNormalLanes; ++j)
    {
      const float px = x[i + j], py = y[i + j], pe = e[i + j], sigma = inv_sigma[i + j];
      // Both loaded, then a select: a conditional load is a branch on targets without masked loads (SSE4, NEON).
      const float is = range2[i + j] <= radius2 ? sigma : 0.0f;
      const float u = (pe - (a + b * px + c * py)) * is * inv_window;
      const float v = std::max(0.0f, 1.0f - u * u);
      const float w = v * v * is * is;
      acc[0][j] += w;
      acc[1][j] += w * px;
      acc[2][j] += w * py;
      acc[3][j] += w * px * px;
      acc[4][j] += w * px * py;
      acc[5][j] += w * py * py;
      acc[6][j] += w * pe;
      acc[7][j] += w * pe * px;
      acc[8][j] += w * pe * py;
    }
  for (int k = 0; k < 9; ++k)
  {
    double s = 0.0;
    for (int j = 0; j < kNormalLanes; ++j)
      s += acc[k][j];
    out[k] = s;
  }
}
}  // namespace HWY_NAMESPACE
}  // namespace detail
}  // namespace kinect_pipeline
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kinect_pipeline
{
namespace detail
{
HWY_EXPORT(normalEquationsOf);
void normalEquations(const float* x, const float* y, const float* e, const float* inv_sigma, const float* range2, int n,
                     float a, float b, float c, float inv_window, float radius2, double out[9])
{
  HWY_DYNAMIC_DISPATCH(normalEquationsOf)(x, y, e, inv_sigma, range2, n, a, b, c, inv_window, radius2, out);
}
}  // namespace detail
}  // namespace kinect_pipeline
#endif  // HWY_ONCE
