/**
 * @file compressed_depth.h
 * @brief compressedDepth payloads (compressed_depth_image_transport's sensor_msgs/CompressedImage) to and from
 *        depth images, without ROS.
 *
 * A payload is a 12-byte header, then the image compressed by PNG (16-bit grayscale) or RVL:
 *
 *   bytes 0-3   int32   compression format (0, INV_DEPTH; read but not checked, as upstream does)
 *   bytes 4-7   float   depthQuantA  (32FC1 only; 0 for 16UC1)
 *   bytes 8-11  float   depthQuantB  (32FC1 only; 0 for 16UC1)
 *   bytes 12-   PNG file, or RVL: uint32 width, uint32 height, then RVL's 32-bit words
 *
 * all little-endian. 16UC1 images are stored as they are (millimetres). 32FC1 images (metres) are stored as
 * 16-bit inverse depth: with z0 = depth_quantization and depth_max,
 *
 *   depthQuantA = z0 (z0 + 1),  depthQuantB = 1 - depthQuantA / depth_max   (float)
 *   value = (uint16) (depthQuantA / depth + depthQuantB)  (truncated)   for 0 < depth < depth_max, else 0
 *   depth = depthQuantA / (value - depthQuantB)  for value != 0;  value 0 -> NaN
 *
 * so a decoded depth d' is never nearer than the original d and errs by at most d'^2 / (depthQuantA + d')
 * (1 m: 0.1 mm, 5 m: 2.5 mm, 10 m: 9.9 mm with the defaults). Source: ros-perception/image_transport_plugins,
 * compressed_depth_image_transport/src/codec.cpp (encodeCompressedDepthImage / decodeCompressedDepthImage).
 */
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/model/camera.h"
#include "kinect_pipeline/model/encoding.h"

namespace kinect_pipeline
{

/** How the image after the 12-byte header is compressed. */
enum class DepthCodec
{
  kPng,  ///< a PNG file, 16-bit grayscale
  kRvl,  ///< RVL run-length / variable-length code (Wilson 2017), after a uint32 width and height
};

/** @return "png" or "rvl". */
std::string toString(DepthCodec c);

/**
 * @brief "png" or "rvl" as a DepthCodec.
 * @throw std::invalid_argument naming @p name and the two accepted names.
 */
DepthCodec depthCodecFromString(const std::string& name);

/** What a CompressedImage's `format` string says about its payload. */
struct CompressedDepthFormat
{
  Encoding encoding = Encoding::kMono16;  ///< kMono16 (16UC1 mm) or kFloat32 (32FC1 m)
  DepthCodec codec = DepthCodec::kPng;
};

/**
 * @brief Parses a compressedDepth `format` string.
 *
 * Accepted (spaces around the parts are ignored):
 *   "<enc>; compressedDepth"       PNG (ROS Melodic and older)
 *   "<enc>; compressedDepth png"   PNG (Noetic, ROS 2)
 *   "<enc>; compressedDepth rvl"   RVL (Noetic, ROS 2)
 * with <enc> one of 16UC1, mono16 (both: uint16 millimetres) or 32FC1 (float metres); and, as upstream reads a
 * format without ';', "16UC1", "mono16" or "32FC1" alone (PNG), "png" (16UC1 PNG) or "rvl" (16UC1 RVL).
 * @throw std::invalid_argument naming @p format and what was expected (an unknown encoding, codec, or a format
 *        of another transport such as compressed_image_transport's "16UC1; png compressed").
 */
CompressedDepthFormat parseCompressedDepthFormat(const std::string& format);

/** @return the format string upstream writes today: "16UC1; compressedDepth png", "32FC1; compressedDepth rvl". */
std::string compressedDepthFormatString(const CompressedDepthFormat& format);

/** Bytes of the header in front of the compressed image. */
constexpr std::size_t kCompressedDepthHeaderBytes = 12;

/**
 * @brief Decodes a compressedDepth payload into a depth image.
 *
 * A 16UC1 PNG payload without the header (a bare PNG file, which upstream's decoder refuses) is read as well:
 * the PNG signature cannot be a header (its first four bytes are no compression format). A 32FC1 payload needs
 * its header: without it the quantisation is unknown.
 *
 * @param format the CompressedImage's `format` (see parseCompressedDepthFormat)
 * @param data, size the CompressedImage's `data`
 * @param expected the size the image must have (from camera_info, or the previous frame); empty: any size
 * @return CV_16UC1 [mm, 0 = no measurement] for 16UC1 / mono16, CV_32FC1 [m, NaN = no measurement] for 32FC1;
 *         a new, continuous image
 * @throw std::invalid_argument naming the bad value and what was expected: a bad format, a payload shorter
 *        than its header, an image that is no PNG or does not decode, a PNG that is not 16-bit grayscale, a
 *        32FC1 header whose quantisation is not finite and non-zero, a malformed RVL stream, a width or height outside
 *        1..kMaxImageSide (as a Camera; refused before any memory is reserved) or other than @p expected
 */
cv::Mat decodeCompressedDepth(const std::string& format, const std::uint8_t* data, std::size_t size,
                              cv::Size expected = cv::Size());

/** @brief decodeCompressedDepth of a byte vector (a CompressedImage's `data`). */
cv::Mat decodeCompressedDepth(const std::string& format, const std::vector<std::uint8_t>& data,
                              cv::Size expected = cv::Size());

/**
 * @brief Decodes a CompressedImage of depth of either of image_transport's transports: compressedDepth as
 *        decodeCompressedDepth() (a format with "compressedDepth", or without ';'), and compressed_image_transport's
 *        lossless PNG of 16-bit depth, "16UC1; png compressed" or "mono16; png compressed" (spaces around the parts
 *        ignored), as the bare 16-bit PNG it is (CV_16UC1 mm). JPEG, 8-bit and colour are no depth.
 * @throw std::invalid_argument naming @p format and the formats read where it is neither; else as
 *        decodeCompressedDepth()
 */
cv::Mat decodeDepthImage(const std::string& format, const std::uint8_t* data, std::size_t size,
                         cv::Size expected = cv::Size());

/** compressed_depth_image_transport's publisher parameters, with its defaults. */
struct CompressedDepthOptions
{
  DepthCodec codec = DepthCodec::kPng;
  double depth_max = 10.0;            ///< [m] deeper pixels are written as 0 (no measurement), in both encodings
  double depth_quantization = 100.0;  ///< z0 of the 32FC1 inverse-depth quantisation [m]; larger: finer
  int png_level = 1;                  ///< zlib level of the PNG, 0 (none) to 9 (smallest)
};

/** A CompressedImage's `format` and `data`. */
struct CompressedDepth
{
  std::string format;
  std::vector<std::uint8_t> data;
};

/**
 * @brief Encodes a depth image as compressed_depth_image_transport does (same header, same quantisation; the
 *        PNG by cv::imencode).
 *
 * 16UC1: pixels above depth_max (in mm) become 0. 32FC1: NaN, +-Inf, depths <= 0, >= depth_max, or nearer than
 * depthQuantA / (65536 - depthQuantB) (0.152 m with the defaults: no 16-bit value holds them; upstream's
 * conversion overflows) become 0, which decodes to NaN.
 * @param depth CV_16UC1 [mm] or CV_32FC1 [m], not empty
 * @return format "16UC1; compressedDepth png" (or 32FC1, or rvl) and the payload
 * @throw std::invalid_argument for another image type, an empty image, depth_max or depth_quantization not finite
 *        and positive, png_level outside 0..9
 */
CompressedDepth encodeCompressedDepth(const cv::Mat& depth, const CompressedDepthOptions& options = {});

}  // namespace kinect_pipeline
