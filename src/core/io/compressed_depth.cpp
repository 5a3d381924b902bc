// compressedDepth payloads (image_transport's format): why the node decodes them itself, docs/ros_node.md,
// "compressedDepth without the plugin".
#include "kinect_pipeline/io/compressed_depth.h"

#include <algorithm>
#include <climits>
#include <cmath>
#include <cstring>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>

#include <opencv2/imgcodecs.hpp>

namespace kinect_pipeline
{
namespace
{
// The facts below (header layout, the format strings, the quantisation, RVL's bit layout) are those of
// ros-perception/image_transport_plugins, compressed_depth_image_transport (codec.cpp, compression_common.h,
// rvl_codec.cpp); the code is this package's own, with every length and run checked before it is used.
constexpr std::uint8_t kPngSignature[8] = {0x89, 0x50, 0x4e, 0x47, 0x0d, 0x0a, 0x1a, 0x0a};
constexpr std::size_t kPngIhdrEnd = 33;     // signature, IHDR length and type, 13 bytes of IHDR, its CRC
constexpr std::int32_t kInvDepth = 0;       // upstream's compressionFormat INV_DEPTH, the only one it writes
constexpr std::size_t kRvlSizeBytes = 8;    // uint32 width, uint32 height
constexpr int kMaxVleNibbles = 11;          // 33 bits: more than any run or delta of a valid stream
constexpr const char* kFormatsExpected =
    "expected '<encoding>; compressedDepth', '<encoding>; compressedDepth png' or '<encoding>; compressedDepth rvl' "
    "with <encoding> 16UC1, mono16 or 32FC1";

template <typename... Args>
[[noreturn]] void fail(const Args&... parts)
{
  std::ostringstream s;
  (s << ... << parts);
  throw std::invalid_argument(s.str());
}

std::string trim(const std::string& s)
{
  const auto first = s.find_first_not_of(" \t");
  return first == std::string::npos ? std::string() : s.substr(first, s.find_last_not_of(" \t") - first + 1);
}

std::uint32_t readLe32(const std::uint8_t* p)
{
  return std::uint32_t{p[0]} | std::uint32_t{p[1]} << 8 | std::uint32_t{p[2]} << 16 | std::uint32_t{p[3]} << 24;
}

std::uint32_t readBe32(const std::uint8_t* p)
{
  return std::uint32_t{p[3]} | std::uint32_t{p[2]} << 8 | std::uint32_t{p[1]} << 16 | std::uint32_t{p[0]} << 24;
}

void appendLe32(std::vector<std::uint8_t>& out, std::uint32_t v)
{
  for (int shift = 0; shift < 32; shift += 8)
    out.push_back(static_cast<std::uint8_t>(v >> shift));
}

float floatFromBits(std::uint32_t bits)
{
  float f;
  std::memcpy(&f, &bits, sizeof f);
  return f;
}

std::uint32_t bitsOfFloat(float f)
{
  std::uint32_t bits;
  std::memcpy(&bits, &f, sizeof f);
  return bits;
}

std::string hexBytes(const std::uint8_t* p, std::size_t n)
{
  std::ostringstream s;
  for (std::size_t i = 0; i < n; ++i)
    s << (i ? " " : "") << std::hex << std::setw(2) << std::setfill('0') << int{p[i]};
  return s.str();
}

// ---------------------------------------------------------------- format strings

bool encodingByName(const std::string& name, Encoding& e)
{
  if (name == "16UC1" || name == "mono16")
    e = Encoding::kMono16;
  else if (name == "32FC1")
    e = Encoding::kFloat32;
  else
    return false;
  return true;
}

/** A format without ';': upstream reads it as the encoding, compressed by PNG; "png" and "rvl" alone are 16UC1. */
CompressedDepthFormat parseFormatWithoutSemicolon(const std::string& format)
{
  const std::string name = trim(format);
  CompressedDepthFormat f;
  if (name == "png" || name == "rvl")
    f.codec = depthCodecFromString(name);
  else if (!encodingByName(name, f.encoding))
    fail("compressedDepth format '", format, "': ", kFormatsExpected,
         " (or, from older publishers, the encoding alone, 'png' or 'rvl')");
  return f;
}

// ---------------------------------------------------------------- payload

struct Header
{
  std::int32_t format = kInvDepth;
  float quant_a = 0.0f, quant_b = 0.0f;  // depthQuantA, depthQuantB
};

/** The compressed image and the header before it (none for a bare legacy PNG). */
struct Payload
{
  bool has_header = true;
  Header header;
  const std::uint8_t* image = nullptr;
  std::size_t size = 0;
};

bool startsWithPngSignature(const std::uint8_t* p, std::size_t n)
{
  return n >= sizeof kPngSignature && std::memcmp(p, kPngSignature, sizeof kPngSignature) == 0;
}

Payload splitPayload(const CompressedDepthFormat& f, const std::uint8_t* data, std::size_t size)
{
  if (f.codec == DepthCodec::kPng && startsWithPngSignature(data, size))
    return {false, Header{}, data, size};
  if (size < kCompressedDepthHeaderBytes)
    fail("compressedDepth payload of ", size, " bytes: shorter than its ", kCompressedDepthHeaderBytes,
         "-byte header (compression format, depthQuantA, depthQuantB)");
  if (size == kCompressedDepthHeaderBytes)
    fail("compressedDepth payload of ", size, " bytes: a header and no image after it");
  Header h;
  h.format = static_cast<std::int32_t>(readLe32(data));
  h.quant_a = floatFromBits(readLe32(data + 4));
  h.quant_b = floatFromBits(readLe32(data + 8));
  return {true, h, data + kCompressedDepthHeaderBytes, size - kCompressedDepthHeaderBytes};
}

void requireQuantisation(const Payload& p)
{
  if (!p.has_header)
    fail("32FC1 compressedDepth payload without its 12-byte header (it starts with the PNG signature): the "
         "inverse-depth quantisation (depthQuantA, depthQuantB) is unknown");
  const float a = p.header.quant_a, b = p.header.quant_b;
  if (!(std::isfinite(a) && a > 0.0f) || !std::isfinite(b))
    fail("32FC1 compressedDepth header: depthQuantA = ", a, ", depthQuantB = ", b,
         ": expected finite values and depthQuantA > 0 (the publisher's is z0 (z0 + 1))");
}

void checkSize(std::uint32_t width, std::uint32_t height, cv::Size expected, const char* what)
{
  const auto in_range = [](std::uint32_t v) { return v >= 1 && v <= static_cast<std::uint32_t>(kMaxImageSide); };
  if (!in_range(width) || !in_range(height))
    fail(what, " image of ", width, "x", height, " pixels: expected a width and height of 1 to ", kMaxImageSide);
  if (!expected.empty() && (static_cast<int>(width) != expected.width || static_cast<int>(height) != expected.height))
    fail(what, " image of ", width, "x", height, " pixels: expected ", expected.width, "x", expected.height);
}

// ---------------------------------------------------------------- PNG

const char* pngColourTypeName(int type)
{
  switch (type)
  {
    case 0:
      return "grayscale";
    case 2:
      return "RGB";
    case 3:
      return "palette";
    case 4:
      return "grayscale + alpha";
    case 6:
      return "RGBA";
    default:
      return "unknown colour type";
  }
}

cv::Mat decodePng(const std::uint8_t* p, std::size_t n, cv::Size expected)
{
  if (!startsWithPngSignature(p, n))
    fail("compressedDepth image is not a PNG: its first bytes are ", hexBytes(p, std::min<std::size_t>(n, 8)),
         ", expected the PNG signature ", hexBytes(kPngSignature, sizeof kPngSignature));
  if (n < kPngIhdrEnd || std::memcmp(p + 12, "IHDR", 4) != 0)
    fail("PNG of ", n, " bytes without a whole IHDR chunk after its signature: truncated or corrupt");
  if (n > static_cast<std::size_t>(INT_MAX))
    fail("PNG of ", n, " bytes: expected at most ", INT_MAX);
  const std::uint32_t width = readBe32(p + 16), height = readBe32(p + 20);
  const int bit_depth = p[24], colour_type = p[25];
  if (bit_depth != 16 || colour_type != 0)
    fail("PNG is ", bit_depth, "-bit ", pngColourTypeName(colour_type), " (colour type ", colour_type,
         "): expected 16-bit grayscale, one channel");
  checkSize(width, height, expected, "PNG");
  cv::Mat out;
  try
  {
    out = cv::imdecode(cv::Mat(1, static_cast<int>(n), CV_8UC1, const_cast<std::uint8_t*>(p)), cv::IMREAD_UNCHANGED);
  }
  catch (const cv::Exception& e)
  {
    fail("PNG of ", width, "x", height, " (", n, " bytes) does not decode: ", e.what());
  }
  if (out.empty())
    fail("PNG of ", width, "x", height, " (", n, " bytes) does not decode: truncated or corrupt");
  if (out.type() != CV_16UC1 || out.cols != static_cast<int>(width) || out.rows != static_cast<int>(height))
    fail("PNG of ", width, "x", height, " decoded as ", out.cols, "x", out.rows, " with ", out.channels(),
         " channels of ", out.elemSize1() * 8, " bits: expected one 16-bit channel");
  return out;
}

std::vector<std::uint8_t> encodePng(const cv::Mat& image16, int level)
{
  std::vector<std::uint8_t> png;
  if (!cv::imencode(".png", image16, png, {cv::IMWRITE_PNG_COMPRESSION, level}))
    throw std::runtime_error("cv::imencode(.png) failed on a " + std::to_string(image16.cols) + "x" +
                             std::to_string(image16.rows) + " 16-bit image");
  return png;
}

// ---------------------------------------------------------------- RVL
// A stream of little-endian 32-bit words, each holding 8 nibbles, the most significant first. A value is written
// 3 bits per nibble, the lowest first, bit 3 set while more follow. The image, in row-major order, is a sequence of
// (count of zeros, count of non-zeros, each non-zero as the zigzag code of its difference from the previous one).

class NibbleReader
{
public:
  NibbleReader(const std::uint8_t* p, std::size_t n) : p_(p), n_(n) {}

  bool next(unsigned& nibble)
  {
    if (left_ == 0)
    {
      if (n_ - pos_ < 4)
        return false;
      word_ = readLe32(p_ + pos_);
      pos_ += 4;
      left_ = 8;
    }
    nibble = word_ >> 28;
    word_ <<= 4;
    --left_;
    return true;
  }

private:
  const std::uint8_t* p_;
  std::size_t n_, pos_ = 0;
  std::uint32_t word_ = 0;
  int left_ = 0;
};

class NibbleWriter
{
public:
  explicit NibbleWriter(std::vector<std::uint8_t>& out) : out_(out) {}

  void put(unsigned nibble)
  {
    word_ = word_ << 4 | nibble;
    if (++count_ == 8)
    {
      appendLe32(out_, word_);
      word_ = 0;
      count_ = 0;
    }
  }

  /** Writes the last, partly filled word, its nibbles at the top. */
  void finish()
  {
    if (count_)
      appendLe32(out_, word_ << 4 * (8 - count_));
  }

private:
  std::vector<std::uint8_t>& out_;
  std::uint32_t word_ = 0;
  int count_ = 0;
};

void putVle(NibbleWriter& w, std::uint32_t value)
{
  do
  {
    unsigned nibble = value & 7u;
    value >>= 3;
    if (value)
      nibble |= 8u;
    w.put(nibble);
  } while (value);
}

std::uint64_t takeVle(NibbleReader& r, std::size_t done, std::size_t total)
{
  std::uint64_t value = 0;
  unsigned nibble = 0;
  int count = 0;
  do
  {
    if (!r.next(nibble))
      fail("RVL stream ends after ", done, " of ", total, " pixels: truncated");
    if (++count > kMaxVleNibbles)
      fail("RVL stream has a value of more than ", kMaxVleNibbles, " nibbles at pixel ", done, ": corrupt");
    value |= std::uint64_t{nibble & 7u} << (3 * (count - 1));
  } while (nibble & 8u);
  return value;
}

std::uint32_t zigzag(int delta) { return delta >= 0 ? 2u * delta : 2u * static_cast<unsigned>(-delta) - 1u; }

std::int64_t unzigzag(std::uint64_t code)
{
  return (code & 1u) ? -static_cast<std::int64_t>((code + 1) / 2) : static_cast<std::int64_t>(code / 2);
}

std::size_t takeRun(NibbleReader& r, std::size_t done, std::size_t total)
{
  const std::uint64_t run = takeVle(r, done, total);
  if (run > total - done)
    fail("RVL run of ", run, " pixels at pixel ", done, " overruns the image's ", total, " pixels: corrupt");
  return static_cast<std::size_t>(run);
}

void rvlDecode(const std::uint8_t* p, std::size_t n, std::uint16_t* out, std::size_t total)
{
  NibbleReader r(p, n);
  std::size_t done = 0;
  std::uint16_t previous = 0;
  while (done < total)
  {
    const std::size_t zeros = takeRun(r, done, total);
    std::fill(out + done, out + done + zeros, std::uint16_t{0});
    done += zeros;
    if (done == total)
      break;
    const std::size_t nonzeros = takeRun(r, done, total);
    for (std::size_t end = done + nonzeros; done < end; ++done)
    {
      previous = static_cast<std::uint16_t>(previous + unzigzag(takeVle(r, done, total)));
      out[done] = previous;
    }
  }
}

cv::Mat decodeRvl(const std::uint8_t* p, std::size_t n, cv::Size expected)
{
  if (n < kRvlSizeBytes)
    fail("RVL image of ", n, " bytes: shorter than its ", kRvlSizeBytes, "-byte size (uint32 width, height)");
  const std::uint32_t width = readLe32(p), height = readLe32(p + 4);
  checkSize(width, height, expected, "RVL");
  cv::Mat out(static_cast<int>(height), static_cast<int>(width), CV_16UC1);
  rvlDecode(p + kRvlSizeBytes, n - kRvlSizeBytes, out.ptr<std::uint16_t>(), out.total());
  return out;
}

std::vector<std::uint8_t> encodeRvl(const cv::Mat& image16)
{
  const cv::Mat img = image16.isContinuous() ? image16 : image16.clone();
  std::vector<std::uint8_t> out;
  appendLe32(out, static_cast<std::uint32_t>(img.cols));
  appendLe32(out, static_cast<std::uint32_t>(img.rows));
  NibbleWriter w(out);
  const std::uint16_t *p = img.ptr<std::uint16_t>(), *end = p + img.total();
  std::uint16_t previous = 0;
  while (p != end)
  {
    const std::uint16_t* zeros = p;
    while (p != end && *p == 0)
      ++p;
    putVle(w, static_cast<std::uint32_t>(p - zeros));
    const std::uint16_t* nonzeros = p;
    while (p != end && *p != 0)
      ++p;
    putVle(w, static_cast<std::uint32_t>(p - nonzeros));
    for (const std::uint16_t* q = nonzeros; q != p; previous = *q++)
      putVle(w, zigzag(int{*q} - int{previous}));
  }
  w.finish();
  return out;
}

// ---------------------------------------------------------------- depth <-> 16-bit values

cv::Mat inverseDepthToMetres(const cv::Mat& inverse, const Header& h)
{
  cv::Mat out(inverse.size(), CV_32FC1);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int r = 0; r < inverse.rows; ++r)
  {
    const std::uint16_t* in = inverse.ptr<std::uint16_t>(r);
    float* o = out.ptr<float>(r);
    for (int c = 0; c < inverse.cols; ++c)
    {
      const float z = in[c] ? h.quant_a / (static_cast<float>(in[c]) - h.quant_b) : nan;
      o[c] = z > 0.0f && z < std::numeric_limits<float>::infinity() ? z : nan;  // a value below depthQuantB: none
    }
  }
  return out;
}

/** Upstream's quantisation; what no 16-bit value holds (unknown, too far, too near) is 0. */
cv::Mat metresToInverseDepth(const cv::Mat& metres, float a, float b, float depth_max)
{
  cv::Mat out(metres.size(), CV_16UC1);
  for (int r = 0; r < metres.rows; ++r)
  {
    const float* in = metres.ptr<float>(r);
    std::uint16_t* o = out.ptr<std::uint16_t>(r);
    for (int c = 0; c < metres.cols; ++c)
    {
      const float v = in[c] > 0.0f && in[c] < depth_max ? a / in[c] + b : 0.0f;
      o[c] = v < 65536.0f ? static_cast<std::uint16_t>(v) : 0;
    }
  }
  return out;
}

/** 16UC1 pixels above depth_max [m] become 0, as upstream's publisher does. */
cv::Mat dropBeyond(const cv::Mat& millimetres, double depth_max)
{
  cv::Mat out = millimetres.clone();
  const double limit = depth_max * 1000.0;
  if (limit < 65535.0)
    out.setTo(0, out > static_cast<std::uint16_t>(limit));
  return out;
}

void validate(const CompressedDepthOptions& o)
{
  if (!(std::isfinite(o.depth_max) && o.depth_max > 0.0))
    fail("CompressedDepthOptions.depth_max = ", o.depth_max, ": expected a finite depth > 0 m");
  // The publisher's own range (its dynamic_reconfigure): beyond it, 16 bits of inverse depth keep little or nothing
  // (z0 = 1e-6: errors of metres; 1e6: no pixel representable).
  if (!(o.depth_quantization >= 1.0 && o.depth_quantization <= 150.0))
    fail("CompressedDepthOptions.depth_quantization = ", o.depth_quantization,
         ": expected 1 to 150 m (compressed_depth_image_transport's range; default 100)");
  if (o.png_level < 0 || o.png_level > 9)
    fail("CompressedDepthOptions.png_level = ", o.png_level, ": expected 0 (none) to 9 (smallest)");
}

}  // namespace

std::string toString(DepthCodec c) { return c == DepthCodec::kPng ? "png" : "rvl"; }

DepthCodec depthCodecFromString(const std::string& name)
{
  if (name == "png")
    return DepthCodec::kPng;
  if (name == "rvl")
    return DepthCodec::kRvl;
  fail("compressedDepth codec '", name, "': expected png or rvl");
}

CompressedDepthFormat parseCompressedDepthFormat(const std::string& format)
{
  const std::size_t semicolon = format.find(';');
  if (semicolon == std::string::npos)
    return parseFormatWithoutSemicolon(format);
  CompressedDepthFormat f;
  const std::string encoding = trim(format.substr(0, semicolon));
  if (!encodingByName(encoding, f.encoding))
    fail("compressedDepth format '", format, "': encoding '", encoding, "': expected 16UC1, mono16 or 32FC1");
  std::istringstream words(format.substr(semicolon + 1));
  std::string transport, codec, extra;
  words >> transport >> codec >> extra;
  if (transport != "compressedDepth" || !extra.empty())
    fail("compressedDepth format '", format, "': after ';' '", trim(format.substr(semicolon + 1)),
         "': expected 'compressedDepth', 'compressedDepth png' or 'compressedDepth rvl'");
  if (!codec.empty())
    f.codec = depthCodecFromString(codec);
  return f;
}

std::string compressedDepthFormatString(const CompressedDepthFormat& format)
{
  return toString(format.encoding) + "; compressedDepth " + toString(format.codec);
}

cv::Mat decodeCompressedDepth(const std::string& format, const std::uint8_t* data, std::size_t size,
                              cv::Size expected)
{
  const CompressedDepthFormat f = parseCompressedDepthFormat(format);
  const Payload p = splitPayload(f, data, size);
  if (f.encoding == Encoding::kFloat32)
    requireQuantisation(p);
  cv::Mat image = f.codec == DepthCodec::kPng ? decodePng(p.image, p.size, expected)
                                               : decodeRvl(p.image, p.size, expected);
  return f.encoding == Encoding::kFloat32 ? inverseDepthToMetres(image, p.header) : image;
}

cv::Mat decodeCompressedDepth(const std::string& format, const std::vector<std::uint8_t>& data, cv::Size expected)
{
  return decodeCompressedDepth(format, data.data(), data.size(), expected);
}

namespace
{
// compressed_image_transport's "<encoding>; <codec> compressed [<target>]" of a lossless 16-bit depth PNG.
bool isPngCompressedDepth(const std::string& format)
{
  const std::size_t semicolon = format.find(';');
  if (semicolon == std::string::npos)
    return false;
  const std::string encoding = trim(format.substr(0, semicolon));
  std::istringstream words(format.substr(semicolon + 1));
  std::string codec, compressed;
  words >> codec >> compressed;
  return compressed == "compressed" && codec == "png" && (encoding == "16UC1" || encoding == "mono16");
}
}  // namespace

cv::Mat decodeDepthImage(const std::string& format, const std::uint8_t* data, std::size_t size, cv::Size expected)
{
  if (isPngCompressedDepth(format))
    return decodeCompressedDepth("16UC1; compressedDepth png", data, size, expected);  // a bare 16-bit PNG
  if (format.find("compressedDepth") != std::string::npos || format.find(';') == std::string::npos)
    return decodeCompressedDepth(format, data, size, expected);
  fail("CompressedImage format '", format, "': not a depth image this package reads; it reads '16UC1; png ",
       "compressed' and 'mono16; png compressed' (image_transport's compressed transport: a PNG of 16-bit depth) ",
       "and compressedDepth ('16UC1; compressedDepth png', '... rvl', '32FC1; compressedDepth ...')");
}

CompressedDepth encodeCompressedDepth(const cv::Mat& depth, const CompressedDepthOptions& options)
{
  validate(options);
  if (depth.empty() || (depth.type() != CV_16UC1 && depth.type() != CV_32FC1))
    fail("depth image of ", depth.cols, "x", depth.rows, " type ", cv::typeToString(depth.type()),
         ": expected a non-empty CV_16UC1 (mm) or CV_32FC1 (m) image");
  CompressedDepthFormat f{depth.type() == CV_16UC1 ? Encoding::kMono16 : Encoding::kFloat32, options.codec};
  Header h;
  cv::Mat image16;
  if (f.encoding == Encoding::kFloat32)
  {
    const float z0 = static_cast<float>(options.depth_quantization);
    const float depth_max = static_cast<float>(options.depth_max);
    h.quant_a = z0 * (z0 + 1.0f);
    h.quant_b = 1.0f - h.quant_a / depth_max;
    image16 = metresToInverseDepth(depth, h.quant_a, h.quant_b, depth_max);
  }
  else
  {
    image16 = dropBeyond(depth, options.depth_max);
  }
  CompressedDepth out;
  out.format = compressedDepthFormatString(f);
  appendLe32(out.data, static_cast<std::uint32_t>(h.format));
  appendLe32(out.data, bitsOfFloat(h.quant_a));
  appendLe32(out.data, bitsOfFloat(h.quant_b));
  const std::vector<std::uint8_t> body = f.codec == DepthCodec::kPng ? encodePng(image16, options.png_level)
                                                                      : encodeRvl(image16);
  out.data.insert(out.data.end(), body.begin(), body.end());
  return out;
}

}  // namespace kinect_pipeline
