// Benchmark of the core pipeline: median time per stage and per frame for 512x424 frames of each encoding,
// 1 and 2 threads, next to a memcpy of the same frame measured in the same run, and their ratio.
// Also counts heap allocations per frame in steady state (global operator new is counted here).
//
// --simd restricts the kernels' run-time dispatch to one SIMD target (kinect_pipeline/simd.h); a list measures each
// target in turn, side by side, in one run.
//
//   kinect_pipeline_bench [--frames N] [--kernel K] [--projection horizontal|column] [--threads 1,2,...]
//                         [--encodings 8UC1,...] [--simd native,avx2,...] [--markdown]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <cmath>
#include <string>
#include <vector>

#include <opencv2/core/utility.hpp>

#include "kinect_pipeline/pipeline.h"
#include "kinect_pipeline/simd.h"
#include "kinect_pipeline/tools/synthetic.h"

namespace
{
std::atomic<long> g_allocations{0};
}

void* operator new(std::size_t n)
{
  g_allocations.fetch_add(1, std::memory_order_relaxed);
  if (void* p = std::malloc(n ? n : 1))
    return p;
  throw std::bad_alloc();
}
void operator delete(void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }

using namespace kinect_pipeline;
using Clock = std::chrono::steady_clock;

namespace
{
double median(std::vector<double> v)
{
  std::sort(v.begin(), v.end());
  return v.empty() ? 0.0 : v[v.size() / 2];
}

// "a,b,c" -> {a, b, c} (the list options).
std::vector<std::string> commaList(const std::string& list)
{
  std::vector<std::string> out;
  for (std::size_t at = 0; at <= list.size();)
  {
    const std::size_t comma = std::min(list.find(',', at), list.size());
    if (comma > at)
      out.push_back(list.substr(at, comma - at));
    at = comma + 1;
  }
  return out;
}

double ms(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double, std::milli>(b - a).count(); }

// A lab-like scene: benches, a desk, a person-sized box, low clutter, a real ceiling at 2.6 m.
Scene labScene()
{
  Scene s;
  s.ceiling = 2.6;
  s.boxes = {{2.0, 2.6, -1.8, -0.6, 0.0, 0.9}, {3.5, 4.2, 0.4, 1.6, 0.7, 0.78}, {3.5, 3.6, 0.4, 0.5, 0.0, 0.7},
             {1.6, 1.9, 0.3, 0.6, 0.0, 1.75}, {1.2, 1.35, -0.2, 0.0, 0.0, 0.10}, {5.5, 5.8, -2.5, 2.5, 0.0, 2.6},
             {2.8, 3.0, -0.4, -0.2, 0.0, 0.05}};
  return s;
}
}  // namespace

int main(int argc, char** argv)
{
  int frames = 300, kernel = 3;
  double surface_band = 0.0;
  bool refine_floor = true;
  std::vector<int> thread_counts = {1, 2};
  std::string projection = "horizontal";
  bool markdown = false;
  std::vector<int> types = {CV_8UC1, CV_16UC1, CV_32FC1};
  // KINECT_PIPELINE_SIMD is the default of --simd here (restrictSimd of each run would otherwise undo it).
  const char* env_simd = std::getenv("KINECT_PIPELINE_SIMD");
  std::vector<std::string> simds = {env_simd && *env_simd ? env_simd : "native"};
  for (int i = 1; i < argc; ++i)
  {
    const std::string a = argv[i];
    if (a == "--frames" && i + 1 < argc)
      frames = std::atoi(argv[++i]);
    else if (a == "--kernel" && i + 1 < argc)
      kernel = std::atoi(argv[++i]);
    else if (a == "--projection" && i + 1 < argc)
      projection = argv[++i];
    else if (a == "--encodings" && i + 1 < argc)
    {
      // A comma-separated subset of 8UC1,16UC1,32FC1 (profiling one encoding).
      types.clear();
      for (const std::string& e : commaList(argv[++i]))
      {
        if (e == "8UC1")
          types.push_back(CV_8UC1);
        else if (e == "16UC1")
          types.push_back(CV_16UC1);
        else if (e == "32FC1")
          types.push_back(CV_32FC1);
        else
        {
          std::fprintf(stderr, "--encodings: '%s' is not one of 8UC1, 16UC1, 32FC1\n", e.c_str());
          return 2;
        }
      }
    }
    else if (a == "--surface-band" && i + 1 < argc)
      surface_band = std::atof(argv[++i]);
    else if (a == "--no-refine-floor")
      refine_floor = false;
    else if (a == "--markdown")
      markdown = true;
    else if (a == "--simd" && i + 1 < argc)
      simds = commaList(argv[++i]);
    else if (a == "--threads" && i + 1 < argc)
    {
      // A comma-separated list, e.g. 1,2,4,8,16; the first is the speed-up's reference.
      thread_counts.clear();
      for (const std::string& t : commaList(argv[++i]))
      {
        const int n = std::atoi(t.c_str());
        if (n < 1 || n > 1024)
        {
          std::fprintf(stderr, "--threads: '%s' is not a thread count 1..1024\n", t.c_str());
          return 2;
        }
        thread_counts.push_back(n);
      }
    }
    else
    {
      std::fprintf(stderr, "usage: %s [--frames N] [--kernel K] [--projection horizontal|column] [--threads 1,2,...] [--encodings 8UC1,16UC1,32FC1] [--simd native|avx512|avx2|sse4|scalar,...] [--surface-band B] [--no-refine-floor] [--markdown]\n", argv[0]);
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }

  for (const std::string& t : simds)
    try
    {
      restrictSimd(t);
    }
    catch (const std::invalid_argument& e)
    {
      std::fprintf(stderr, "%s: %s\n", env_simd && simds.size() == 1 && t == env_simd ? "KINECT_PIPELINE_SIMD" : "--simd",
                   e.what());
      return 2;
    }
  // The scene is rendered with OpenCV, whose own worker threads (TBB) would then spin on the CPUs for a while,
  // beside the frames' OpenMP threads: the pipeline uses no OpenCV threads, and the bench renders on one.
  cv::setNumThreads(0);
  const Camera cam = Camera::fromFov(512, 424, 1.2322, 1.0472);
  const double height = 1.1, pitch = 0.26;
  Rendering rendering;
  renderScene(cam, height, pitch, 0.0, labScene(), rendering);
  cv::Mat metres = rendering.depth.clone();
  addKinectNoise(metres, 1);

  struct Row
  {
    std::string enc, simd;
    int threads;
    double memcpy_ms, total, prepare, floor_fit, erode, classify, confidence;
    double allocs;
  };
  std::vector<Row> rows;
  for (const int type : types)
  {
    const cv::Mat frame = encodeDepth(metres, type, 12.0);
    cv::Mat copy(frame.size(), frame.type());
    const std::size_t bytes = frame.total() * frame.elemSize();
    for (const int threads : thread_counts)
      for (const std::string& simd : simds)
    {
      restrictSimd(simd);
      const std::string ran = simd == "native" ? "native (" + simdTarget() + ")" : simdTarget();
      Config cfg;
      cfg.sensor_height = height;
      cfg.sensor_pitch = pitch;
      cfg.open_kernel_size = kernel;
      cfg.projection = projectionFromString(projection);
      cfg.num_threads = threads;
      cfg.surface_band = surface_band;
      cfg.refine_floor = refine_floor;
      Pipeline pipe(cam, cfg);
      FrameResult res;
      // Warm-up, with a pitch that changes every frame as on a Segway (the plane terms are recomputed).
      for (int i = 0; i < 30; ++i)
        pipe.process(frame, 0.01 * std::sin(i * 0.3), 0.0, res);
      std::vector<double> tm, tt, tp, tff, te, tc, tf;
      long allocs = 0;
      for (int i = 0; i < frames; ++i)
      {
        auto a = Clock::now();
        std::memcpy(copy.data, frame.data, bytes);
        auto b = Clock::now();
        tm.push_back(ms(a, b));
        const long before = g_allocations.load();
        pipe.process(frame, 0.01 * std::sin(i * 0.3), 0.0, res);
        allocs += g_allocations.load() - before;
        tt.push_back(res.times.total);
        tp.push_back(res.times.prepare);
        tff.push_back(res.times.floor_fit);
        te.push_back(res.times.erode);
        tc.push_back(res.times.classify_scan);
        tf.push_back(res.times.confidence);
      }
      rows.push_back({toString(type == CV_8UC1 ? Encoding::kMono8 : type == CV_16UC1 ? Encoding::kMono16 : Encoding::kFloat32),
                      ran, threads, median(tm), median(tt), median(tp), median(tff), median(te), median(tc), median(tf),
                      static_cast<double>(allocs) / frames});
    }
  }

  std::printf("kinect_pipeline core benchmark: 512x424, %d frames each, opening %dx%d rect, %s projection, "
              "surface_band %g, pitch changing every frame\n",
              frames, kernel, kernel, projection.c_str(), surface_band);
  if (markdown)
  {
    std::printf("| encoding | simd | threads | memcpy [ms] | prepare | (floor fit) | erode | classify+scan | confidence | "
                "frame [ms] | frame / memcpy | floor fit / frame | speed-up vs 1 thread | allocations / frame |\n");
    std::printf("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n");
  }
  else
  {
    std::printf("%-6s %-15s %3s %9s %8s %9s %8s %9s %8s %9s %8s %9s %8s %7s\n", "enc", "simd", "thr", "memcpy", "prepare",
                "floor fit", "erode", "classify", "conf", "frame", "x memcpy", "fit/frame", "speedup", "allocs");
  }
  for (std::size_t i = 0; i < rows.size(); ++i)
  {
    const Row& r = rows[i];
    const std::size_t per_enc = thread_counts.size() * simds.size();
    const double one = rows[i - i % per_enc + i % simds.size()].total;  // this encoding's and target's first thread count
    const double speedup = one / r.total;
    if (markdown)
      std::printf("| %s | %s | %d | %.4f | %.4f | %.4f | %.4f | %.4f | %.4f | %.4f | %.1f | %.1f %% | %.2f | %.1f |\n",
                  r.enc.c_str(), r.simd.c_str(), r.threads, r.memcpy_ms, r.prepare, r.floor_fit, r.erode, r.classify, r.confidence,
                  r.total, r.total / r.memcpy_ms, 100.0 * r.floor_fit / r.total, speedup, r.allocs);
    else
      std::printf("%-6s %-15s %3d %9.4f %8.4f %9.4f %8.4f %9.4f %8.4f %9.4f %8.1f %8.1f%% %8.2f %7.1f\n", r.enc.c_str(),
                  r.simd.c_str(), r.threads, r.memcpy_ms, r.prepare, r.floor_fit, r.erode, r.classify, r.confidence, r.total,
                  r.total / r.memcpy_ms, 100.0 * r.floor_fit / r.total, speedup, r.allocs);
  }
  std::printf("(times are medians in ms; 'x memcpy' = frame / memcpy of the same frame in the same run; the floor fit is "
              "part of prepare, and 'fit/frame' its share of the frame)\n");
  return 0;
}
