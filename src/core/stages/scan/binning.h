// Private to the core: the scan binning of stage 2, the pixels of a row's span into the beams (ScanProjector's
// geometry, stages/scan.h), by the bins' border crossings where the horizontal projection allows it, else by the pixel
// centres' bearings; and each projection's binning of a frame. Design notes: docs/core_design.md ("The scan").
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <vector>

#include <opencv2/core.hpp>

#include "kinect_pipeline/stages/scan.h"
#include "kinect_pipeline/types.h"
#include "stages/frame_common.h"
#include "stages/scan/cliff_rule.h"

namespace kinect_pipeline
{
namespace detail
{
// What the binning does with a range v that goes into bin k (k may be a padding slot, -1 or beams).
struct MinInto  // the nearest range per bin
{
  float* bins;
  void operator()(int k, float v) const { bins[k] = v < bins[k] ? v : bins[k]; }
};
struct MinCountInto  // the nearest range per bin, and how many finite ranges went in
{
  float* bins;
  std::int32_t* counts;
  void operator()(int k, float v) const
  {
    bins[k] = v < bins[k] ? v : bins[k];
    counts[k] += v < kInf;
  }
};
struct BandSum  // sum [um] and number of the ranges no farther than limit[k] (exact integers: any order, any team)
{
  const float* limit;
  std::int64_t* sum;
  std::int32_t* n;
  void operator()(int k, float v) const
  {
    const bool in = v <= limit[k];
    sum[k] += static_cast<std::int64_t>(static_cast<double>(in ? v : 0.0f) * 1e6 + 0.5);
    n[k] += in;
  }
};

/** One thread's buffers of the binning, sized once per image size / beam count. */
struct BinScratch
{
  std::vector<float> z;           ///< depth of the row's pixels that go in [m], +Inf for the others
  std::vector<float> range;       ///< beam range of each pixel of the row [m], +Inf for removed ones
  std::vector<float> colmin;      ///< column projection: nearest kept depth per column [m]
  std::vector<float> edges;       ///< bin positions of the row's pixel centres
  std::vector<float> bins;        ///< nearest range per beam seen by this thread (+ a slot either side)
  std::vector<std::int32_t> key;  ///< bin of each pixel centre of the row
  std::vector<std::uint8_t> gaps;  ///< flags: pixels whose next neighbour's centre is more than a bin away
  std::vector<std::int32_t> lo, hi;       ///< the pixels of each bin of the row
  std::vector<float> cliff_bins;          ///< nearest below-floor range per beam (+ padding)
  std::vector<std::int32_t> cliff_count;  ///< below-floor pixels per beam (+ padding)
  std::vector<std::int64_t> band_sum;     ///< surface_band: ranges within the band per beam [um] (+ padding)
  std::vector<std::int32_t> band_n;       ///< surface_band: their number per beam (+ padding)
  float cov_lo = 0.0f, cov_hi = 0.0f;     ///< ScanProjector::rowCoverage over this thread's rows
  void resize(std::size_t w, std::size_t beams);
};

/** The depths of a span that the caller put in BinScratch::z (+Inf where nothing is seen); bins get ranges. */
struct SpanDepths
{
};

/**
 * The depths of the kept pixels of a cleaned row (+Inf for removed ones), read where they are needed; bins get
 * squared ranges (ScanProjector::spanKeptSquaredRanges), rooted once per beam when the threads' bins are merged.
 */
template <typename T>
struct KeptDepths
{
  const T* row;
  float scale;
};

/**
 * Bins spans of rows into beams. The horizontal projection finds each bin's pixels from where its borders cross the
 * row (ScanProjector::spanPlan), where that holds; the rest (the column projection, rows that look nearly straight
 * down, and every row with centres_only) bin their pixel centres by their bearings (ScanProjector::spanBins): the
 * same bins up to float rounding at a bin's border.
 */
class RowBinner
{
public:
  /** @param paths binning: every row by its centres' bearings (the reference path); portable: the
   *  pull's plain reference instead of its SIMD kernel */
  RowBinner(const ScanProjector& projector, int width, const ReferencePaths& paths)
      : p_(projector), width_(width), centres_only_(paths.binning), vector_(!paths.portable)
  {
  }
  const ScanProjector& projector() const { return p_; }
  /** @return ScanProjector::spanPlan's n (-1: bin by the centres; always with centres_only) and the plan. */
  int plan(int r, int a, int b, SpanPlan& plan) const { return centres_only_ ? -1 : p_.spanPlan(r, a, b, plan); }
  /**
   * Bins the span a..b of row r, whose depths src gives (SpanDepths: in s.z; KeptDepths), into acc. One pixel
   * either side goes in as +Inf too: a gap between the span's end and its neighbour is split between them.
   */
  template <typename Acc, typename Src>
  void bin(int r, int a, int b, BinScratch& s, const Src& src, const Acc& acc) const
  {
    SpanPlan sp;
    const int n = plan(r, a, b, sp);
    bin(r, a, b, n, sp, s, src, acc);
  }
  /** bin() with the span's plan and plan()'s n already found. */
  template <typename Acc, typename Src>
  void bin(int r, int a, int b, int n, const SpanPlan& plan, BinScratch& s, const Src& src, const Acc& acc) const;
  /** Bins the centres u0..u1 of row r, of depths z (+Inf where nothing is seen), as squared ranges or ranges. */
  template <typename Acc>
  void binCentres(int r, int u0, int u1, const float* z, BinScratch& s, bool squared, const Acc& acc) const;

private:
  const ScanProjector& p_;
  int width_;
  bool centres_only_;
  bool vector_;  ///< the SIMD pull (detail::pullNearest); false: its plain reference, bin by bin
};

/**
 * z[u] = opened depth of the pixel u labelled below floor where it is cliff evidence (CliffRule::evidence, the ray's
 * rise col[u] + row), +Inf for the others, u in [u0, u1].
 */
template <typename T>
void belowFloorDepth(const T* src, const std::uint8_t* lab, int u0, int u1, float scale, const float* col, float row,
                     const CliffRule& rule, float* z);
/** First and last column with the label l (the row has one). */
int firstLabelled(const std::uint8_t* lab, int w, std::uint8_t l);
int lastLabelled(const std::uint8_t* lab, int w, std::uint8_t l);

/**
 * The horizontal projection's binning of a frame: each row's kept span into the thread's bins as squared ranges,
 * a chunk of rows at a time (the chunk's plans first, then their pixels: the CPU overlaps the rows' chains of
 * dependent operations), and the coverage of the thread's rows.
 */
template <typename T>
class HorizontalBinning
{
public:
  static constexpr bool kSquared = true;  ///< the bins hold squared ranges (KeptDepths)
  HorizontalBinning(const RowBinner& binner, const cv::Mat& cleaned, const std::int32_t* spans, float scale)
      : binner_(binner), cleaned_(cleaned), spans_(spans), scale_(scale)
  {
  }
  /** In the parallel region, before the rows: this thread's share of the coverage (a loop without barrier). */
  void begin(BinScratch& s, int h) const;
  void keptSpan(int, int, int, const T*, BinScratch&) const {}
  /** After the rows r0..r1 - 1 of a chunk are labelled: bins their kept spans. */
  void chunk(int r0, int r1, BinScratch& s) const;
  void end(BinScratch&) const {}
  /** After the parallel region: the range of bin positions the image covers, from the threads' shares. */
  void coverage(const std::vector<const BinScratch*>& team, float& lo, float& hi) const;

private:
  const RowBinner& binner_;
  const cv::Mat& cleaned_;
  const std::int32_t* spans_;
  float scale_;
};

/**
 * The column projection's binning of a frame: a column's bin and range factor do not depend on the row, so each
 * thread keeps the nearest kept depth per column and bins its columns once, after its rows.
 */
template <typename T>
class ColumnBinning
{
public:
  static constexpr bool kSquared = false;
  ColumnBinning(const RowBinner& binner, float scale) : binner_(binner), scale_(scale) {}
  void begin(BinScratch& s, int h) const;
  void keptSpan(int r, int a, int b, const T* dst, BinScratch& s) const;
  void chunk(int, int, BinScratch&) const {}
  /** After every row of the frame (a barrier): bins the thread's column minima. */
  void end(BinScratch& s) const;
  void coverage(const std::vector<const BinScratch*>& team, float& lo, float& hi) const;

private:
  const RowBinner& binner_;
  float scale_;
};

/**
 * surface_band > 0: each beam's range becomes the mean of its ranges no farther than surface_band * t(m) beyond its
 * nearest m (ranges on entry). A second pass over the kept spans, binned exactly as the first, at the measured
 * depth of the kept pixels: the opening's max of mins is biased towards the sensor on noise (by about one sigma),
 * the raw depth is not. (Raw >= opened, so no raw range lies below m.)
 * @param spans first and last kept column of each row, @param limit scratch of beams + 2 floats
 */
template <typename T>
void surfaceMeans(const RowBinner& binner, const cv::Mat& depth, const cv::Mat& labels, const std::int32_t* spans,
                  const Config& config, int threads, std::vector<BinScratch*>& scratch, std::vector<float>& limit,
                  std::vector<float>& ranges);
}  // namespace detail
}  // namespace kinect_pipeline
