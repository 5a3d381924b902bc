// compressedDepth payloads: round trips, payloads built by hand byte by byte, and every refusal's message.
// The reference is written out here: the header's bytes, upstream's inverse-depth formula and its error bound.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <iterator>
#include <limits>
#include <random>
#include <string>
#include <vector>

#include <opencv2/imgcodecs.hpp>

#include "kinect_pipeline/io/compressed_depth.h"
#include "test_util.h"

using namespace kinect_pipeline;
using kp_test::expectInvalid;
using Bytes = std::vector<std::uint8_t>;

namespace
{
const float kNan = std::numeric_limits<float>::quiet_NaN();
const float kInf = std::numeric_limits<float>::infinity();

// The 16UC1 header: compression format 0 (INV_DEPTH), depthQuantA = depthQuantB = 0.
const Bytes kHeader16 = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
// The 32FC1 header for upstream's defaults z0 = 100, depth_max = 10 m: A = 100 * 101 = 10100 (0x461dd000),
// B = 1 - 10100 / 10 = -1009 (0xc47c4000), little-endian.
const Bytes kHeader32 = {0, 0, 0, 0, 0x00, 0xd0, 0x1d, 0x46, 0x00, 0x40, 0x7c, 0xc4};

Bytes png(const cv::Mat& img)
{
  Bytes out;
  EXPECT_TRUE(cv::imencode(".png", img, out));
  return out;
}

Bytes concat(Bytes a, const Bytes& b)
{
  a.insert(a.end(), b.begin(), b.end());
  return a;
}

cv::Mat1w randomMillimetres(int rows, int cols, std::uint32_t seed, int max_mm)
{
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> mm(0, max_mm), hole(0, 9);
  cv::Mat1w m(rows, cols);
  for (auto& v : m)
    v = static_cast<std::uint16_t>(hole(rng) == 0 ? 0 : mm(rng));  // ~10 % holes: zero runs for RVL
  return m;
}

void expectSameMillimetres(const cv::Mat& got, const cv::Mat1w& want)
{
  ASSERT_EQ(got.type(), CV_16UC1);
  ASSERT_EQ(got.size(), want.size());
  for (int r = 0; r < want.rows; ++r)
    for (int c = 0; c < want.cols; ++c)
      ASSERT_EQ(got.at<std::uint16_t>(r, c), want(r, c)) << "at (" << r << ", " << c << ")";
}

/** What upstream's 32FC1 quantisation keeps of depth d [m], with z0 and depth_max as in its publisher. */
struct InverseDepthReference
{
  double z0 = 100.0, depth_max = 10.0;
  float a() const { return static_cast<float>(z0) * (static_cast<float>(z0) + 1.0f); }
  float b() const { return 1.0f - a() / static_cast<float>(depth_max); }
  // Representable: 0 < d < depth_max, and A / d + B below 65536 (nearer ones overflow 16 bits).
  bool kept(float d) const { return d > 0.0f && d < depth_max && a() / d + b() < 65536.0f; }
  // The value is truncated, so the decoded d' = A / (v - B) is >= d, and d > A / (v + 1 - B) gives
  // d' - d < d'^2 / (A + d'); float rounding of the formula adds a few ulp.
  double maxError(double decoded) const { return decoded * decoded / (a() + decoded) + 1e-6 * decoded; }
};

void expectWithinQuantisation(const cv::Mat& got, const cv::Mat1f& want, const InverseDepthReference& ref)
{
  ASSERT_EQ(got.type(), CV_32FC1);
  ASSERT_EQ(got.size(), want.size());
  for (int r = 0; r < want.rows; ++r)
    for (int c = 0; c < want.cols; ++c)
    {
      const float d = want(r, c), decoded = got.at<float>(r, c);
      if (!ref.kept(d))
      {
        ASSERT_TRUE(std::isnan(decoded)) << d << " m decoded as " << decoded << " at (" << r << ", " << c << ")";
        continue;
      }
      ASSERT_GE(decoded, d - 1e-6 * d) << "at (" << r << ", " << c << ")";
      ASSERT_LE(decoded - d, ref.maxError(decoded)) << d << " m decoded as " << decoded;
    }
}

cv::Mat1f metresWithEveryKindOfPixel()
{
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> m(0.16f, 9.99f);
  cv::Mat1f d(48, 64);
  for (auto& v : d)
    v = m(rng);
  const float specials[] = {kNan, kInf, -kInf, 0.0f, -1.0f, 10.0f, 12.0f, 0.1f, 0.152f, 9.9999f, 2.0f};
  for (int i = 0; i < static_cast<int>(std::size(specials)); ++i)
    d(0, i) = specials[i];
  return d;
}
}  // namespace

// ---------------------------------------------------------------- format strings

TEST(CompressedDepthFormat, ReadsWhatPublishersWrite)
{
  struct Case
  {
    const char* format;
    Encoding encoding;
    DepthCodec codec;
  };
  const Case cases[] = {
      {"16UC1; compressedDepth", Encoding::kMono16, DepthCodec::kPng},
      {"16UC1; compressedDepth png", Encoding::kMono16, DepthCodec::kPng},
      {"16UC1; compressedDepth rvl", Encoding::kMono16, DepthCodec::kRvl},
      {"32FC1; compressedDepth", Encoding::kFloat32, DepthCodec::kPng},
      {"32FC1; compressedDepth png", Encoding::kFloat32, DepthCodec::kPng},
      {"32FC1; compressedDepth rvl", Encoding::kFloat32, DepthCodec::kRvl},
      {"mono16; compressedDepth png", Encoding::kMono16, DepthCodec::kPng},
      {" 16UC1 ;  compressedDepth  png ", Encoding::kMono16, DepthCodec::kPng},
      {"16UC1", Encoding::kMono16, DepthCodec::kPng},
      {"32FC1", Encoding::kFloat32, DepthCodec::kPng},
      {"png", Encoding::kMono16, DepthCodec::kPng},
      {"rvl", Encoding::kMono16, DepthCodec::kRvl},
  };
  for (const Case& c : cases)
  {
    const CompressedDepthFormat f = parseCompressedDepthFormat(c.format);
    EXPECT_EQ(f.encoding, c.encoding) << c.format;
    EXPECT_EQ(f.codec, c.codec) << c.format;
  }
  EXPECT_EQ(compressedDepthFormatString({Encoding::kFloat32, DepthCodec::kRvl}), "32FC1; compressedDepth rvl");
  EXPECT_EQ(compressedDepthFormatString({Encoding::kMono16, DepthCodec::kPng}), "16UC1; compressedDepth png");
}

TEST(CompressedDepthFormat, RefusesOthersNamingThem)
{
  expectInvalid([] { parseCompressedDepthFormat("8UC1; compressedDepth"); }, {"'8UC1'", "16UC1", "32FC1"});
  expectInvalid([] { parseCompressedDepthFormat("16UC1; compressedDepth jpeg"); }, {"'jpeg'", "png or rvl"});
  expectInvalid([] { parseCompressedDepthFormat("16UC1; png compressed"); },
                {"'16UC1; png compressed'", "'png compressed'", "compressedDepth png"});
  expectInvalid([] { parseCompressedDepthFormat("16UC1; compressedDepth png extra"); },
                {"'compressedDepth png extra'"});
  expectInvalid([] { parseCompressedDepthFormat("jpeg"); }, {"'jpeg'", "compressedDepth"});
  expectInvalid([] { parseCompressedDepthFormat(""); }, {"''", "compressedDepth"});
  expectInvalid([] { depthCodecFromString("zstd"); }, {"'zstd'", "png or rvl"});
}

// A CompressedImage of depth of either transport: compressedDepth as decodeCompressedDepth, and the compressed
// transport's PNG of 16-bit depth; other compressed images named with what is read.
TEST(DepthImage, BothTransportsAreReadAndOthersNamed)
{
  cv::Mat mm(3, 5, CV_16UC1);
  for (int k = 0; k < 15; ++k)
    mm.at<std::uint16_t>(k / 5, k % 5) = static_cast<std::uint16_t>(400 + 131 * k);
  std::vector<std::uint8_t> png;
  ASSERT_TRUE(cv::imencode(".png", mm, png));
  for (const char* format : {"16UC1; png compressed", "mono16; png compressed", " 16UC1 ;  png  compressed "})
    EXPECT_EQ(cv::norm(decodeDepthImage(format, png.data(), png.size()), mm, cv::NORM_INF), 0.0) << format;
  const CompressedDepth c = encodeCompressedDepth(mm, {});
  EXPECT_EQ(cv::norm(decodeDepthImage(c.format, c.data.data(), c.data.size()), mm, cv::NORM_INF), 0.0);
  expectInvalid([&] { decodeDepthImage("mono8; jpeg compressed", png.data(), png.size()); },
                {"'mono8; jpeg compressed'", "not a depth image", "'16UC1; png compressed'", "compressedDepth png"});
  expectInvalid([&] { decodeDepthImage("16UC1; jpeg compressed", png.data(), png.size()); }, {"not a depth image"});
  expectInvalid([&] { decodeDepthImage("16UC1; compressedDepth jpeg", png.data(), png.size()); }, {"'jpeg'"});
}

// ---------------------------------------------------------------- round trips

TEST(CompressedDepth, Millimetres16RoundTripExactlyInBothCodecs)
{
  const cv::Mat1w mm = randomMillimetres(53, 71, 1, 10000);  // odd sizes: no row or word alignment to lean on
  for (DepthCodec codec : {DepthCodec::kPng, DepthCodec::kRvl})
  {
    CompressedDepthOptions o;
    o.codec = codec;
    const CompressedDepth c = encodeCompressedDepth(mm, o);
    EXPECT_EQ(c.format, "16UC1; compressedDepth " + toString(codec));
    ASSERT_GT(c.data.size(), 12u);
    EXPECT_EQ(Bytes(c.data.begin(), c.data.begin() + 12), kHeader16);
    expectSameMillimetres(decodeCompressedDepth(c.format, c.data), mm);
    expectSameMillimetres(decodeCompressedDepth(c.format, c.data, cv::Size(71, 53)), mm);
  }
}

TEST(CompressedDepth, RvlKeepsEveryValueAndRun)
{
  // Whole-range jumps (deltas of +-65535), long zero runs, a zero run at the end and one at the start.
  cv::Mat1w mm(3, 1000, std::uint16_t{0});
  mm(0, 1) = 65535;
  mm(0, 2) = 1;
  mm(0, 3) = 65535;
  for (int c = 100; c < 900; ++c)
    mm(1, c) = static_cast<std::uint16_t>(c * 73);
  mm(2, 0) = 5;
  CompressedDepthOptions o;
  o.codec = DepthCodec::kRvl;
  o.depth_max = 70.0;  // keeps 65535 mm
  const CompressedDepth c = encodeCompressedDepth(mm, o);
  expectSameMillimetres(decodeCompressedDepth(c.format, c.data), mm);
  const cv::Mat1w all_zero(4, 5, std::uint16_t{0});
  expectSameMillimetres(decodeCompressedDepth(c.format, encodeCompressedDepth(all_zero, o).data), all_zero);
}

TEST(CompressedDepth, Millimetres16BeyondDepthMaxBecomeZero)
{
  cv::Mat1w mm(1, 4);
  mm << 999, 1000, 1001, 65535;
  CompressedDepthOptions o;
  o.depth_max = 1.0;
  cv::Mat1w want(1, 4);
  want << 999, 1000, 0, 0;
  const CompressedDepth c = encodeCompressedDepth(mm, o);
  expectSameMillimetres(decodeCompressedDepth(c.format, c.data), want);
}

TEST(CompressedDepth, Metres32RoundTripWithinTheQuantisationInBothCodecs)
{
  const cv::Mat1f m = metresWithEveryKindOfPixel();
  for (DepthCodec codec : {DepthCodec::kPng, DepthCodec::kRvl})
    for (double z0 : {100.0, 75.0})
    {
      CompressedDepthOptions o;
      o.codec = codec;
      o.depth_quantization = z0;
      InverseDepthReference ref;
      ref.z0 = z0;
      const CompressedDepth c = encodeCompressedDepth(m, o);
      EXPECT_EQ(c.format, "32FC1; compressedDepth " + toString(codec));
      float a, b;
      std::memcpy(&a, &c.data[4], 4);
      std::memcpy(&b, &c.data[8], 4);
      EXPECT_EQ(a, ref.a());
      EXPECT_EQ(b, ref.b());
      expectWithinQuantisation(decodeCompressedDepth(c.format, c.data), m, ref);
    }
}

TEST(CompressedDepth, Metres32AreTruncatedToTheNextInverseDepthStep)
{
  // Defaults: A = 10100, B = -1009. 2 m -> 5050 - 1009 = 4041 exactly -> 2 m; 3 m -> 2357.67 -> 2357 ->
  // 10100 / 3366 m; 1 m -> 9091 -> 1 m.
  cv::Mat1f m(1, 3);
  m << 2.0f, 3.0f, 1.0f;
  const CompressedDepth c = encodeCompressedDepth(m);
  EXPECT_EQ(Bytes(c.data.begin(), c.data.begin() + 12), kHeader32);
  const cv::Mat1w values = cv::imdecode(Bytes(c.data.begin() + 12, c.data.end()), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(values.size(), m.size());
  EXPECT_EQ(values(0, 0), 4041);
  EXPECT_EQ(values(0, 1), 2357);
  EXPECT_EQ(values(0, 2), 9091);
  const cv::Mat1f back = decodeCompressedDepth(c.format, c.data);
  EXPECT_FLOAT_EQ(back(0, 0), 2.0f);
  EXPECT_FLOAT_EQ(back(0, 1), 10100.0f / 3366.0f);
  EXPECT_FLOAT_EQ(back(0, 2), 1.0f);
}

// ---------------------------------------------------------------- payloads made by hand

TEST(CompressedDepth, HandBuilt16BitPngPayloadDecodesToItsValues)
{
  cv::Mat1w mm(2, 3);
  mm << 0, 1, 500, 1234, 40000, 65535;
  for (const char* format : {"16UC1; compressedDepth", "16UC1; compressedDepth png", "mono16; compressedDepth"})
    expectSameMillimetres(decodeCompressedDepth(format, concat(kHeader16, png(mm))), mm);
}

TEST(CompressedDepth, HandBuilt32BitPngPayloadDecodesToItsDepths)
{
  // depth = 10100 / (v + 1009): v = 1 -> 10 m, 4041 -> 2 m, 9091 -> 1 m, 19191 -> 0.5 m; 0 -> NaN.
  cv::Mat1w inverse(1, 5);
  inverse << 0, 1, 4041, 9091, 19191;
  const cv::Mat1f d = decodeCompressedDepth("32FC1; compressedDepth png", concat(kHeader32, png(inverse)));
  ASSERT_EQ(d.size(), inverse.size());
  EXPECT_TRUE(std::isnan(d(0, 0)));
  EXPECT_FLOAT_EQ(d(0, 1), 10.0f);
  EXPECT_FLOAT_EQ(d(0, 2), 2.0f);
  EXPECT_FLOAT_EQ(d(0, 3), 1.0f);
  EXPECT_FLOAT_EQ(d(0, 4), 0.5f);
}

TEST(CompressedDepth, HandBuiltRvlPayloadDecodesToItsValues)
{
  // 3x1 image 0 0 5: zeros 2 (nibble 2), non-zeros 1 (nibble 1), delta +5 -> zigzag 10 = 0b1010 -> nibbles
  // a (010 + more), 1. One word with the nibbles at the top: 0x21a10000, little-endian.
  const Bytes rvl = {3, 0, 0, 0, 1, 0, 0, 0, 0x00, 0x00, 0xa1, 0x21};
  cv::Mat1w want(1, 3);
  want << 0, 0, 5;
  expectSameMillimetres(decodeCompressedDepth("16UC1; compressedDepth rvl", concat(kHeader16, rvl)), want);
  // Our encoder writes those very bytes.
  CompressedDepthOptions o;
  o.codec = DepthCodec::kRvl;
  EXPECT_EQ(encodeCompressedDepth(want, o).data, concat(kHeader16, rvl));
  // 5x1 image 0 5 0 5 0 in exactly one word, ending with the last zero run (no count of 0 non-zeros after it):
  // 1 zero, 1 non-zero, zigzag 10 (a 1), 1 zero, 1 non-zero, zigzag 0 (0), 1 zero = 0x11a11101.
  const Bytes rvl5 = {5, 0, 0, 0, 1, 0, 0, 0, 0x01, 0x11, 0xa1, 0x11};
  cv::Mat1w want5(1, 5);
  want5 << 0, 5, 0, 5, 0;
  expectSameMillimetres(decodeCompressedDepth("16UC1; compressedDepth rvl", concat(kHeader16, rvl5)), want5);
}

TEST(CompressedDepth, BarePngWithoutHeaderIsRead16BitOnly)
{
  // A 16UC1 payload that is a PNG file and no header (upstream's decoder refuses it): its signature's first
  // four bytes are no compression format, so it cannot be mistaken for a header.
  cv::Mat1w mm(2, 2);
  mm << 1, 2, 3, 4;
  expectSameMillimetres(decodeCompressedDepth("16UC1; compressedDepth", png(mm)), mm);
  expectInvalid([&] { decodeCompressedDepth("32FC1; compressedDepth", png(mm)); },
                {"32FC1", "12-byte header", "depthQuantA"});
}

// ---------------------------------------------------------------- bad payloads

TEST(CompressedDepth, RefusesShortPayloads)
{
  expectInvalid([] { decodeCompressedDepth("16UC1; compressedDepth", Bytes(5, 0)); }, {"5 bytes", "12-byte header"});
  expectInvalid([] { decodeCompressedDepth("16UC1; compressedDepth", Bytes()); }, {"0 bytes", "12-byte header"});
  expectInvalid([] { decodeCompressedDepth("16UC1; compressedDepth", nullptr, 0); }, {"0 bytes"});
  expectInvalid([] { decodeCompressedDepth("16UC1; compressedDepth", kHeader16); }, {"12 bytes", "no image"});
  expectInvalid([] { decodeCompressedDepth("16UC1; compressedDepthx", kHeader16); }, {"'16UC1; compressedDepthx'"});
}

TEST(CompressedDepth, RefusesWhatIsNoSixteenBitGrayPng)
{
  const Bytes jpeg_start = {0xff, 0xd8, 0xff, 0xe0, 0, 0x10, 'J', 'F', 'I', 'F'};
  expectInvalid([&] { decodeCompressedDepth("16UC1; compressedDepth", concat(kHeader16, jpeg_start)); },
                {"not a PNG", "ff d8 ff e0", "89 50 4e 47 0d 0a 1a 0a"});
  const cv::Mat1b eight(4, 4, std::uint8_t{7});
  expectInvalid([&] { decodeCompressedDepth("16UC1; compressedDepth", concat(kHeader16, png(eight))); },
                {"8-bit grayscale", "expected 16-bit grayscale"});
  const cv::Mat rgb16(4, 4, CV_16UC3, cv::Scalar(1, 2, 3));
  expectInvalid([&] { decodeCompressedDepth("16UC1; compressedDepth png", concat(kHeader16, png(rgb16))); },
                {"16-bit RGB", "colour type 2", "one channel"});
  Bytes cut = png(randomMillimetres(40, 40, 2, 9000));
  cut.resize(cut.size() / 2);
  expectInvalid([&] { decodeCompressedDepth("16UC1; compressedDepth", concat(kHeader16, cut)); },
                {"PNG of 40x40", "does not decode"});
  Bytes head_only = png(cv::Mat1w(2, 2, std::uint16_t{1}));
  head_only.resize(20);
  expectInvalid([&] { decodeCompressedDepth("16UC1; compressedDepth", concat(kHeader16, head_only)); },
                {"20 bytes", "IHDR"});
}

TEST(CompressedDepth, RefusesSizesOtherThanExpected)
{
  const cv::Mat1w mm = randomMillimetres(3, 4, 3, 5000);
  for (DepthCodec codec : {DepthCodec::kPng, DepthCodec::kRvl})
  {
    CompressedDepthOptions o;
    o.codec = codec;
    const CompressedDepth c = encodeCompressedDepth(mm, o);
    expectInvalid([&] { decodeCompressedDepth(c.format, c.data, cv::Size(640, 480)); },
                  {"4x3 pixels", "expected 640x480"});
  }
}

TEST(CompressedDepth, Refuses32BitHeadersWithoutAQuantisation)
{
  const Bytes body = png(cv::Mat1w(2, 2, std::uint16_t{100}));
  const Bytes nan_a = {0, 0, 0, 0, 0x00, 0x00, 0xc0, 0x7f, 0x00, 0x40, 0x7c, 0xc4};  // A = NaN (0x7fc00000)
  expectInvalid([&] { decodeCompressedDepth("32FC1; compressedDepth", concat(nan_a, body)); },
                {"depthQuantA = nan", "finite"});
  expectInvalid([&] { decodeCompressedDepth("32FC1; compressedDepth", concat(kHeader16, body)); },
                {"depthQuantA = 0", "> 0"});
  // A = -1: every depth came back negative, as if valid.
  const Bytes negative_a = {0, 0, 0, 0, 0x00, 0x00, 0x80, 0xbf, 0x00, 0x00, 0x00, 0x00};
  expectInvalid([&] { decodeCompressedDepth("32FC1; compressedDepth", concat(negative_a, body)); },
                {"depthQuantA = -1", "> 0"});
}

TEST(CompressedDepth, RefusesMalformedRvl)
{
  const auto rvl = [](const Bytes& body) {
    return [body] { decodeCompressedDepth("16UC1; compressedDepth rvl", concat(kHeader16, body)); };
  };
  expectInvalid(rvl({3, 0, 0}), {"3 bytes", "8-byte size"});
  expectInvalid(rvl({0, 0, 0, 0, 1, 0, 0, 0, 0, 0, 0, 0}), {"0x1 pixels", "1 to 16384"});
  expectInvalid(rvl({0, 0, 1, 0, 0, 0, 1, 0}), {"65536x65536 pixels", "1 to 16384"});
  // 3x1 but the stream says 7 zeros.
  expectInvalid(rvl({3, 0, 0, 0, 1, 0, 0, 0, 0x00, 0x00, 0x00, 0x70}), {"run of 7 pixels", "3 pixels"});
  // 3x1 and no stream.
  expectInvalid(rvl({3, 0, 0, 0, 1, 0, 0, 0}), {"ends after 0 of 3 pixels"});
  // 3x1, 2 zeros and then only empty runs to the end of the word; a last, partial word is not read.
  expectInvalid(rvl({3, 0, 0, 0, 1, 0, 0, 0, 0x00, 0x00, 0x00, 0x20, 0xa0}), {"ends after 2 of 3 pixels"});
  // Twelve continued nibbles: no valid value is that long.
  expectInvalid(rvl({3, 0, 0, 0, 1, 0, 0, 0, 0x88, 0x88, 0x88, 0x88, 0x88, 0x88, 0x88, 0x88}), {"11 nibbles"});
  // The size is checked before the stream is read.
  expectInvalid([] { decodeCompressedDepth("rvl", concat(kHeader16, {3, 0, 0, 0, 1, 0, 0, 0}), cv::Size(2, 2)); },
                {"3x1 pixels", "expected 2x2"});
}

// ---------------------------------------------------------------- encoder refusals

TEST(CompressedDepth, EncoderRefusesOtherImagesAndOptions)
{
  expectInvalid([] { encodeCompressedDepth(cv::Mat1b(2, 2, std::uint8_t{1})); }, {"8UC1", "CV_16UC1", "CV_32FC1"});
  expectInvalid([] { encodeCompressedDepth(cv::Mat(2, 2, CV_32FC3)); }, {"32FC3"});
  expectInvalid([] { encodeCompressedDepth(cv::Mat()); }, {"0x0", "non-empty"});
  const cv::Mat1f m(2, 2, 1.0f);
  const auto with = [&](auto set) {
    return [&m, set] {
      CompressedDepthOptions o;
      set(o);
      encodeCompressedDepth(m, o);
    };
  };
  expectInvalid(with([](CompressedDepthOptions& o) { o.depth_max = 0.0; }), {"depth_max = 0", "> 0"});
  expectInvalid(with([](CompressedDepthOptions& o) { o.depth_max = NAN; }), {"depth_max = nan"});
  expectInvalid(with([](CompressedDepthOptions& o) { o.depth_quantization = -1.0; }), {"depth_quantization = -1"});
  // Outside the publisher's range, 16 bits of inverse depth keep nothing (1e6) or errors of metres (1e-6).
  for (const double z0 : {1e-6, 0.5, 151.0, 1e6})
    expectInvalid(with([z0](CompressedDepthOptions& o) { o.depth_quantization = z0; }),
                  {"depth_quantization", "1 to 150"});
  expectInvalid(with([](CompressedDepthOptions& o) { o.png_level = 10; }), {"png_level = 10", "0 (none) to 9"});
}
