// Private to the core: how the floor fit and the floor profile sample a frame (the same grid, the same test for
// vertical surfaces). Design notes: docs/floor_refinement.md.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>

namespace kinect_pipeline
{
namespace detail
{
/**
 * About @p samples pixels of a frame: every row_step-th row, each at columns col_step apart from an offset that
 * moves on by the golden ratio from row to row, so that all rows take part (without roll the floor has one depth per
 * row: the rows are the independent samples of an integer encoding's rounding) and the columns are covered evenly.
 */
struct SampleGrid
{
  int row_step, col_step;

  SampleGrid(int width, int height, int row_step_, double samples)
      : row_step(row_step_),
        col_step(std::max(1, static_cast<int>(rows(height) * static_cast<double>(width) / samples)))
  {
  }
  /** @return the sampled rows of a frame of @p height rows. */
  int rows(int height) const { return (height + row_step - 1) / row_step; }
  /** @return the first sampled column of the k-th sampled row. */
  int firstColumn(int k) const
  {
    constexpr double kGolden = 0.6180339887498949;
    return static_cast<int>(std::fmod(k * kGolden, 1.0) * col_step);
  }
};

/// A sampled pixel is checked against the pixel kGradRows rows below it (looksVertical()).
constexpr int kGradRows = 4;

/**
 * @return whether a pixel at depth z [m] on a ray of rise R lies on a vertical surface rather than on the floor,
 * from the depth z2 of the pixel kGradRows rows below it (rise R2): on the floor that pixel sees the same plane
 * farther along another ray (z R / R2), on a vertical surface (a leg, a foot, a table leg, a wall's base) about the
 * same range (kGradRows rows change a ray's horizontal length by well under 1 %, the floor's depth by far more
 * wherever the two can be told apart). True where the two predictions differ by more than t (t(z) [m]) and z2 is
 * nearer the vertical one; false without z2 (no evidence either way).
 */
inline bool looksVertical(float z, float rise, float rise2, float z2, float t)
{
  if (!(z2 > 0.0f))
    return false;
  const float on_floor = rise2 < 0.0f ? z * rise / rise2 : std::numeric_limits<float>::infinity();
  const float on_wall = z;
  return std::fabs(on_floor - on_wall) > t && std::fabs(z2 - on_wall) < std::fabs(z2 - on_floor);
}
}  // namespace detail
}  // namespace kinect_pipeline
