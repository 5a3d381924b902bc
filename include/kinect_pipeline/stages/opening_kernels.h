/**
 * @file morphology.h
 * @brief Row kernels of the rectangular opening, shared by the fused pipeline and the standalone opening.
 */
#pragma once

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/config.h"

namespace kinect_pipeline
{

/**
 * @brief Morphological opening with the same result as cv::morphologyEx(MORPH_OPEN) (default border,
 *        centred anchor), without allocating when @p dst already has the right size and type.
 * @param src 8UC1, 16UC1 or 32FC1 image (no NaN: map unknown pixels first)
 * @param dst output, may not alias @p src
 * @param ksize odd kernel size >= 3
 * @param shape kRect uses the separable row kernels below; other shapes call OpenCV
 * @param scratch intermediate image (reused)
 * @throw std::invalid_argument for an even or < 3 size or another type.
 */
void morphOpen(const cv::Mat& src, cv::Mat& dst, int ksize, KernelShape shape, cv::Mat& scratch);

namespace detail
{
// Plain loops, compiled once per SIMD target and dispatched at run time (kinect_pipeline/simd.h).
/** dst[u] = min (or max) of src rows r - rad .. r + rad (clamped) then of columns u - rad .. u + rad. */
template <typename T, bool kMin>
void rectRow(const cv::Mat& src, int r, int rad, T* tmp, T* dst);
/** Same as rectRow<T, true> but maps unknown pixels of @p src to DepthTraits<T>::kNoReturn first. */
template <typename T>
void erodeMappedRow(const cv::Mat& src, int r, int rad, T* tmp, T* dst);
/**
 * rectRow<T, false> of a 3x3 kernel from the three rows given (a above b, c below; at the image's top and bottom
 * edges pass b again): for dilating rows whose eroded neighbours are held elsewhere than in an image.
 */
template <typename T>
void dilate3Rows(const T* a, const T* b, const T* c, int w, T* dst);
}  // namespace detail

}  // namespace kinect_pipeline
