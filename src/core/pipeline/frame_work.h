// Private to the core: the buffers of a Pipeline's frames, per thread and per frame, sized once per image size and
// beam count (no allocation per frame). Design notes: docs/core_design.md ("Buffers").
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <vector>

#include "kinect_pipeline/pipeline.h"
#include "stages/labels/by_value.h"
#include "stages/opening/opening.h"
#include "stages/scan/binning.h"

namespace kinect_pipeline
{
namespace detail
{
/** One thread's buffers. */
struct ThreadScratch
{
  OpeningScratch opening;
  BinScratch bins;
  std::vector<float> t;                  ///< threshold of each pixel of the row [m]
  std::vector<float> fh;                 ///< floor offset of each pixel of the row, with a floor profile [m]
  std::vector<std::int32_t> steps;       ///< the floor profile's lift step of each pixel of the row
  std::vector<std::uint8_t> cand;        ///< the rescue's flags of the row
  std::vector<std::uint8_t> vlab, vdst;  ///< labels of the 256 values (8-bit rows by value)
  std::array<std::uint64_t, kNumLabels> counts{};

  void resize(std::size_t w, std::size_t beams)
  {
    opening.resize(w);
    bins.resize(w, beams);
    t.resize(w);
    fh.resize(w);
    steps.resize(w);
    cand.resize(w + 8);
    vlab.resize(256);
    vdst.resize(256);
  }
  LabelBuffers labelBuffers() { return {t.data(), fh.data(), steps.data(), cand.data(), vlab.data(), vdst.data()}; }
};
/** A Pipeline's frame buffers, and the value labelling's terms of its threshold table. */
struct FrameWork
{
  ValueTerms value_terms;  ///< rebuilt with the threshold table (8- and 16-bit)
  OpeningImages opening;
  std::vector<std::int32_t> spans;        ///< first and last kept column of each row (first > last: none)
  std::vector<std::int32_t> cliff_count;  ///< below-floor pixels per beam of the frame
  std::vector<float> band_limit;          ///< surface_band: farthest range counted per beam (+ padding) [m]
  std::vector<float> samples;             ///< the input check's samples of a float frame (checkMetres)
  cv::Mat despeckled;                     ///< speckle_jump: the input without its wrong matches
  std::vector<std::unique_ptr<ThreadScratch>> scratch;
  std::vector<BinScratch*> bins;  ///< each thread's bins (scratch[i]->bins)
  std::vector<const BinScratch*> team_bins;  ///< those of this frame's team (team())

  void prepare(int threads, int width, int height, int beams)
  {
    if (static_cast<int>(scratch.size()) < threads)
      scratch.resize(threads);
    bins.resize(scratch.size());
    team_bins.reserve(scratch.size());
    for (std::size_t i = 0; i < scratch.size(); ++i)
    {
      if (!scratch[i])
        scratch[i] = std::make_unique<ThreadScratch>();
      if (static_cast<int>(i) < threads)
        scratch[i]->resize(width, beams);
      bins[i] = &scratch[i]->bins;
    }
    spans.resize(2 * static_cast<std::size_t>(height));
  }
  /** The bins of the first n threads (the team of this frame: only theirs hold its sums). */
  const std::vector<const BinScratch*>& team(int n)
  {
    team_bins.assign(bins.begin(), bins.begin() + n);
    return team_bins;
  }
};
}  // namespace detail
}  // namespace kinect_pipeline
