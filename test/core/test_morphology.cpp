#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <limits>
#include <random>
#include <type_traits>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "kinect_pipeline/model/encoding.h"
#include "kinect_pipeline/stages/opening_kernels.h"
#include "stages/speckle.h"
#include "test_util.h"

using namespace kinect_pipeline;

namespace
{
cv::Mat randomImage(int rows, int cols, int type, unsigned seed)
{
  cv::Mat m(rows, cols, type);
  std::mt19937 rng(seed);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
    {
      const unsigned v = rng();
      if (type == CV_8UC1)
        m.at<std::uint8_t>(r, c) = static_cast<std::uint8_t>(v);
      else if (type == CV_16UC1)
        m.at<std::uint16_t>(r, c) = static_cast<std::uint16_t>(v);
      else
        m.at<float>(r, c) = (v % 5 == 0) ? INFINITY : static_cast<float>(v % 10000) / 997.0f;
    }
  return m;
}

using kp_test::sameBits;

// OpenCV's morphologyEx is the slow, obvious reference; the row kernels run on the SIMD target the dispatch picks.
void checkRect(int type, int ksize, int rows, int cols)
{
  const cv::Mat img = randomImage(rows, cols, type, 7 + ksize + rows);
  cv::Mat ref, scratch;
  cv::morphologyEx(img, ref, cv::MORPH_OPEN, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(ksize, ksize)));
  if (type == CV_32FC1)
    ref.setTo(INFINITY, ref == FLT_MAX);  // OpenCV pads float borders with FLT_MAX; both mean "no return"
  cv::Mat got;
  morphOpen(img, got, ksize, KernelShape::kRect, scratch);
  EXPECT_TRUE(sameBits(ref, got)) << kinect_pipeline::simdTarget() << ", type " << type << ", kernel "
                                   << ksize << ", " << rows << "x" << cols;
}

const std::vector<int> kRows = {1, 2, 37};
const std::vector<int> kCols = {1, 2, 3, 31, 32, 33, 63, 64, 65, 66, 127, 128, 131, 512};
}  // namespace

class OpenVsOpenCV : public ::testing::TestWithParam<std::tuple<int, int, int, int>>
{
};

TEST_P(OpenVsOpenCV, RectIsIdentical)
{
  const auto [type, ksize, rows, cols] = GetParam();
  checkRect(type, ksize, rows, cols);
}

INSTANTIATE_TEST_SUITE_P(Types, OpenVsOpenCV,
                         ::testing::Combine(::testing::Values(CV_8UC1, CV_16UC1, CV_32FC1), ::testing::Values(3, 5, 7),
                                            ::testing::ValuesIn(kRows), ::testing::ValuesIn(kCols)));

// The same cases on every SIMD target this CPU has (the row kernels are compiled once per target).
TEST(Morphology, EveryTargetsRectIsIdentical)
{
  const auto ran = kp_test::forEachSimdTarget([](const std::string&) {
    for (const int type : {CV_8UC1, CV_16UC1, CV_32FC1})
      for (const int ksize : {3, 5, 7})
        for (const int rows : kRows)
          for (const int cols : kCols)
            checkRect(type, ksize, rows, cols);
  });
  EXPECT_GE(ran.size(), 2u) << "at least the scalar target and one vector target on x86-64 and aarch64";
}

TEST(Morphology, OtherShapesUseOpenCV)
{
  const cv::Mat img = randomImage(40, 50, CV_16UC1, 3);
  for (auto [shape, cv_shape] : {std::pair{KernelShape::kCross, cv::MORPH_CROSS}, {KernelShape::kEllipse, cv::MORPH_ELLIPSE}})
  {
    cv::Mat ref, got, scratch;
    cv::morphologyEx(img, ref, cv::MORPH_OPEN, cv::getStructuringElement(cv_shape, cv::Size(5, 5)));
    morphOpen(img, got, 5, shape, scratch);
    EXPECT_TRUE(sameBits(ref, got));
  }
}

TEST(Morphology, RefusesEvenKernels)
{
  cv::Mat img(4, 4, CV_8UC1, cv::Scalar(3)), out, scratch;
  EXPECT_THROW(morphOpen(img, out, 4, KernelShape::kRect, scratch), std::invalid_argument);
  EXPECT_THROW(morphOpen(img, out, 1, KernelShape::kRect, scratch), std::invalid_argument);
}

namespace
{
// The erosion of the fused pipeline maps unknown pixels to no-return on the fly (the 3x3 case by an order-preserving
// key, not by mapping): against mapping every pixel first, then OpenCV's erosion.
template <typename T>
void checkErodeMapped(int type, int rows, int cols)
{
  cv::Mat img = randomImage(rows, cols, type, 11 + cols);
  std::mt19937 rng(5 + cols);
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
    {
      const unsigned k = rng() % 8;  // unknown values, and the no-return value itself
      if constexpr (std::is_same_v<T, float>)  // floats: also -0 (unknown) and the smallest depth there is (known)
        img.at<float>(r, c) = k == 0 ? NAN
                              : k == 1 ? 0.0f
                              : k == 2 ? -INFINITY
                              : k == 3 ? -0.0f
                              : k == 4 ? std::numeric_limits<float>::denorm_min()
                                       : img.at<float>(r, c);
      else
        img.at<T>(r, c) = k == 0 ? T(0) : (k == 1 ? T(1) : (k == 2 ? DepthTraits<T>::kNoReturn : img.at<T>(r, c)));
    }
  cv::Mat mapped(img.size(), img.type()), ref;
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c)
      mapped.at<T>(r, c) = DepthTraits<T>::map(img.at<T>(r, c));
  for (const int ksize : {3, 5})
  {
    cv::erode(mapped, ref, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(ksize, ksize)));
    if (type == CV_32FC1)
      ref.setTo(INFINITY, ref == FLT_MAX);
    cv::Mat got(img.size(), img.type());
    std::vector<T> tmp(cols);
    for (int r = 0; r < rows; ++r)
      detail::erodeMappedRow<T>(img, r, ksize / 2, tmp.data(), got.ptr<T>(r));
    EXPECT_TRUE(sameBits(ref, got)) << "type " << type << " size " << rows << "x" << cols << " kernel " << ksize
                                     << " " << kinect_pipeline::simdTarget();
  }
}

void checkAllErodeMapped()
{
  for (const int cols : kCols)
    for (const int rows : {1, 2, 9})
    {
      checkErodeMapped<std::uint8_t>(CV_8UC1, rows, cols);
      checkErodeMapped<std::uint16_t>(CV_16UC1, rows, cols);
      checkErodeMapped<float>(CV_32FC1, rows, cols);
    }
}

}  // namespace

TEST(Morphology, ErodeMappedMatchesMappingFirstOnEveryTarget)
{
  const auto ran = kp_test::forEachSimdTarget([](const std::string&) { checkAllErodeMapped(); });
  EXPECT_GE(ran.size(), 2u);
}

// speckle_jump's wrong matches (stages/speckle.h), on every target, against the rule written out pixel by pixel:
// nearer by more than jump of its depth than each of the four pixels two steps away (no measurement: farther).
namespace
{
template <typename T>
cv::Mat islandsByTheRule(const cv::Mat& in, float factor, int& removed)
{
  const auto at = [&](int v, int u) {
    const T m = DepthTraits<T>::map(in.at<T>(v, u));
    return DepthTraits<T>::isNoReturn(m) ? INFINITY : static_cast<float>(m);
  };
  cv::Mat out = in.clone();
  removed = 0;
  for (int v = 2; v < in.rows - 2; ++v)
    for (int u = 2; u < in.cols - 2; ++u)
    {
      const float z = at(v, u) * factor;
      if (at(v, u - 2) > z && at(v, u + 2) > z && at(v - 2, u) > z && at(v + 2, u) > z)
      {
        out.at<T>(v, u) = T(0);
        ++removed;
      }
    }
  return out;
}

template <typename T>
void checkIslands(int type)
{
  // A noisy surface with dropouts and islands 2 x 2 and 3 x 3 at random nearer depths.
  std::mt19937 rng(11);
  cv::Mat img(37, 45, type);
  std::uniform_real_distribution<float> noise(0.97f, 1.03f), near(0.2f, 0.9f), coin(0.0f, 1.0f);
  const float base = type == CV_8UC1 ? 200.0f : (type == CV_16UC1 ? 3000.0f : 3.0f);
  for (int v = 0; v < img.rows; ++v)
    for (int u = 0; u < img.cols; ++u)
      img.at<T>(v, u) = coin(rng) < 0.05f ? T(0) : static_cast<T>(base * noise(rng));
  for (int k = 0; k < 12; ++k)
  {
    const int s = 2 + k % 2, v = static_cast<int>(coin(rng) * (img.rows - s)), u = static_cast<int>(coin(rng) * (img.cols - s));
    img(cv::Rect(u, v, s, s)).setTo(cv::Scalar(static_cast<double>(static_cast<T>(base * near(rng)))));
  }
  int expected = 0;
  const cv::Mat want = islandsByTheRule<T>(img, 1.125f, expected);
  cv::Mat got;
  EXPECT_EQ(detail::removeSpeckles(img, 0.125, got, 2), expected);
  EXPECT_TRUE(sameBits(want, got));
  EXPECT_GT(expected, 0);
}
}  // namespace

TEST(Speckles, EveryTargetRemovesWhatTheRuleSays)
{
  const auto ran = kp_test::forEachSimdTarget([](const std::string&) {
    checkIslands<std::uint8_t>(CV_8UC1);
    checkIslands<std::uint16_t>(CV_16UC1);
    checkIslands<float>(CV_32FC1);
  });
  EXPECT_GE(ran.size(), 2u);
}
