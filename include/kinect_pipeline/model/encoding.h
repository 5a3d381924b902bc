/**
 * @file encoding.h
 * @brief The three depth encodings and their conventions (depth traits).
 */
#pragma once

#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>

namespace kinect_pipeline
{

/** Depth image encodings the pipeline reads. */
enum class Encoding
{
  kMono8,    ///< 8-bit normalised as in the thesis: depth = v / 255 * max_depth; v < 2 unknown
  kMono16,   ///< 16UC1 millimetres; 0 unknown
  kFloat32,  ///< 32FC1 metres; 0, NaN, +-Inf and negative values unknown
};

/** @return "8UC1", "16UC1" or "32FC1". */
std::string toString(Encoding e);

/**
 * @return the encoding called @p name, one of toString()'s names ("8UC1", "16UC1", "32FC1"; not the message
 *         aliases mono8/mono16, which depthFromBuffer() reads).
 * @throw std::invalid_argument naming @p name and the three names.
 */
Encoding encodingFromString(const std::string& name);

/** @return the depth of one step of the encoding [m] (8-bit: max_depth / 255; 16-bit: 1 mm; float: 0). */
double encodingStep(Encoding e, double max_depth);

/**
 * Per-encoding constants. `kNoReturn` is what an unknown pixel becomes before the opening: the largest
 * value, so that the opening (a min then a max filter) treats it as far background and fills isolated
 * dropouts, as the thesis's 255 does. `removed()` is what a removed pixel is in the cleaned image:
 * 255 for 8-bit (thesis), 0 for 16UC1 and NaN for 32FC1 (what ROS depth consumers read as "no data").
 */
template <typename T>
struct DepthTraits;

template <>
struct DepthTraits<std::uint8_t>
{
  static constexpr Encoding kEncoding = Encoding::kMono8;
  static constexpr std::uint8_t kNoReturn = 255;
  static constexpr std::uint8_t kMinValid = 2;  // thesis eq 4.8
  static std::uint8_t map(std::uint8_t v) { return v < kMinValid ? kNoReturn : v; }
  static bool isNoReturn(std::uint8_t v) { return v == kNoReturn; }
  static std::uint8_t removed() { return 255; }
};

template <>
struct DepthTraits<std::uint16_t>
{
  static constexpr Encoding kEncoding = Encoding::kMono16;
  static constexpr std::uint16_t kNoReturn = 65535;
  static constexpr std::uint16_t kMinValid = 1;  // 0: no measurement
  static std::uint16_t map(std::uint16_t v) { return v < kMinValid ? kNoReturn : v; }
  static bool isNoReturn(std::uint16_t v) { return v == kNoReturn; }
  static std::uint16_t removed() { return 0; }
};

template <>
struct DepthTraits<float>
{
  static constexpr Encoding kEncoding = Encoding::kFloat32;
  static constexpr float kNoReturn = std::numeric_limits<float>::infinity();
  // NaN fails both comparisons, so it maps to no-return as well.
  static float map(float v) { return (v > 0.0f && v < kNoReturn) ? v : kNoReturn; }
  // FLT_MAX counts too: OpenCV's morphology pads float borders with FLT_MAX, not +Inf.
  static bool isNoReturn(float v) { return !(v < std::numeric_limits<float>::max()); }
  static float removed() { return std::numeric_limits<float>::quiet_NaN(); }
};

/**
 * Depth in 32FC1 is metres: an image whose valid pixels have a median above this [m] is plainly in other units
 * (millimetres); the pipeline refuses it, and the tools refuse depth frames read so (Python: MILLIMETRE_MEDIAN).
 */
constexpr float kMillimetreMedian = 100.0f;

/**
 * The depth [m] a pixel v of a cleaned image stands for: +Inf where it was removed (DepthTraits<T>::removed()),
 * else v * scale. Select-free, for the loops that vectorise.
 */
template <typename T>
inline float keptMetres(T v, float scale)
{
  bool gone;
  if constexpr (std::is_floating_point_v<T>)
    gone = v != v;  // NaN
  else
    gone = v == DepthTraits<T>::removed();
  return gone ? std::numeric_limits<float>::infinity() : static_cast<float>(v) * scale;
}

}  // namespace kinect_pipeline
