// Benchmark of the core pipeline: median time per stage and per frame for 512x424 frames of each encoding,
// 1 and 2 threads, next to a memcpy of the same frame measured in the same run, and their ratio.
// Also counts heap allocations per frame in steady state (global operator new is counted here).
//
// --simd restricts the kernels' run-time dispatch to one SIMD target (kinect_pipeline/simd.h); a list measures each
// target in turn, side by side, in one run. --reference does the same for a Pipeline's fast paths
// (ReferencePaths): what each one buys, measured beside the frame that takes them all.
//
// --roll likewise measures frames rendered and processed at each roll given (0 takes the labelling by value, any
// other roll the rule pixel by pixel), side by side.
//
//   kinect_pipeline_bench [--frames N] [--kernel K] [--projection horizontal|column] [--threads 1,2,...]
//                         [--encodings 8UC1,...] [--simd native,avx2,...] [--reference none,labels,...]
//                         [--roll 0,0.0087,...] [--markdown]
#include <algorithm>
#include <atomic>
#include <chrono>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
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

// The sensor's mounting: the scene is rendered there, and the pipelines are told it.
constexpr double kHeight = 1.1, kPitch = 0.26;

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

// "labels+opening" -> those ReferencePaths fields on; "none": the fast paths; "all": every reference path.
bool parseReference(const std::string& name, ReferencePaths& out)
{
  out = {};
  if (name == "all")
    out = ReferencePaths::all();
  else if (name != "none")
    for (std::size_t at = 0; at <= name.size();)
    {
      const std::size_t plus = std::min(name.find('+', at), name.size());
      const std::string f = name.substr(at, plus - at);
      bool* field = f == "labels" ? &out.labels : f == "binning" ? &out.binning : f == "opening" ? &out.opening
                    : f == "portable" ? &out.portable : nullptr;
      if (!field)
        return false;
      *field = true;
      at = plus + 1;
    }
  return true;
}

struct Options
{
  int frames = 300, kernel = 3;
  double surface_band = 0.0;
  std::vector<double> rolls = {0.0};  // the mount's rolls [rad]: frames are rendered and processed at each
  bool refine_floor = true, markdown = false;
  std::vector<int> thread_counts = {1, 2};
  std::string projection = "horizontal";
  std::vector<int> types = {CV_8UC1, CV_16UC1, CV_32FC1};
  std::vector<std::string> simds, references = {"none"};
  bool simd_from_env = false;  // KINECT_PIPELINE_SIMD gave the one target (its name goes into an error)
};

// The whole of text as an integer in [lo, hi] (atoi would take "abc" for 0 and "3x" for 3).
bool integerIn(const char* text, long lo, long hi, int& out)
{
  char* end = nullptr;
  errno = 0;
  const long v = std::strtol(text, &end, 10);
  if (end == text || *end != '\0' || errno != 0 || v < lo || v > hi)
    return false;
  out = static_cast<int>(v);
  return true;
}

// The whole of text as a number (strtod alone would take "3x" for 3).
bool number(const char* text, double& out)
{
  char* end = nullptr;
  out = std::strtod(text, &end);
  return end != text && *end == '\0';
}

// The pipeline's settings of one row of the table.
Config benchConfig(const Options& o, int threads, double roll)
{
  Config cfg;
  cfg.sensor_height = kHeight;
  cfg.sensor_pitch = kPitch;
  cfg.sensor_roll = roll;
  cfg.open_kernel_size = o.kernel;
  cfg.projection = projectionFromString(o.projection);
  cfg.num_threads = threads;
  cfg.surface_band = o.surface_band;
  cfg.refine_floor = o.refine_floor;
  return cfg;
}

// What parseOptions cannot check option by option: a list that names nothing (nothing would be measured), and
// settings the pipeline refuses (Config::validate's message). @return false, with the message on stderr.
bool checkOptions(const Options& o, const char* simd_option)
{
  const std::pair<const char*, bool> lists[] = {{"--encodings", o.types.empty()},
                                                {"--threads", o.thread_counts.empty()},
                                                {simd_option, o.simds.empty()},
                                                {"--reference", o.references.empty()},
                                                {"--roll", o.rolls.empty()}};
  for (const auto& [name, empty] : lists)
    if (empty)
    {
      std::fprintf(stderr, "%s: names nothing to measure: expected a comma-separated list of one or more\n", name);
      return false;
    }
  try
  {
    for (const double roll : o.rolls)
      benchConfig(o, o.thread_counts.front(), roll).validate();
  }
  catch (const std::invalid_argument& e)
  {
    std::fprintf(stderr, "%s\n", e.what());
    return false;
  }
  return true;
}

// The values of a comma-separated list option, each through parse(item, value); false (the item and what was
// expected on stderr) at the first that does not parse. An empty list is checkOptions' to refuse.
template <typename T, typename Parse>
bool listOf(const char* option, const char* text, const char* expected, Parse parse, std::vector<T>& out)
{
  out.clear();
  for (const std::string& item : commaList(text))
  {
    T v{};
    if (!parse(item, v))
    {
      std::fprintf(stderr, "%s: '%s' is not %s\n", option, item.c_str(), expected);
      return false;
    }
    out.push_back(v);
  }
  return true;
}

int encodingType(const std::string& e)
{
  return e == "8UC1" ? CV_8UC1 : e == "16UC1" ? CV_16UC1 : e == "32FC1" ? CV_32FC1 : -1;
}

// @return -1 to go on, else the exit status (after --help, or a bad option with its message on stderr).
int parseOptions(int argc, char** argv, Options& o)
{
  // KINECT_PIPELINE_SIMD is the default of --simd here (restrictSimd of each run would otherwise undo it).
  const char* env_simd = std::getenv("KINECT_PIPELINE_SIMD");
  o.simd_from_env = env_simd && *env_simd;
  o.simds = {o.simd_from_env ? env_simd : "native"};
  for (int i = 1; i < argc; ++i)
  {
    const std::string a = argv[i];
    const bool value = i + 1 < argc;
    if (a == "--frames" && value)
    {
      if (!integerIn(argv[++i], 1, 1000000, o.frames))
      {
        std::fprintf(stderr, "--frames: '%s' is not a frame count 1..1000000\n", argv[i]);
        return 2;
      }
    }
    else if (a == "--kernel" && value)
    {
      if (!integerIn(argv[++i], 0, 31, o.kernel))
      {
        std::fprintf(stderr, "--kernel: '%s' is not an opening kernel size 0..31 px\n", argv[i]);
        return 2;
      }
    }
    else if (a == "--projection" && value)
    {
      o.projection = argv[++i];
      if (o.projection != "horizontal" && o.projection != "column")
      {
        std::fprintf(stderr, "--projection: '%s' is not horizontal or column\n", argv[i]);
        return 2;
      }
    }
    else if (a == "--encodings" && value)  // a subset of 8UC1,16UC1,32FC1 (profiling one encoding)
    {
      const auto parse = [](const std::string& e, int& t) { return (t = encodingType(e)) >= 0; };
      if (!listOf(a.c_str(), argv[++i], "one of 8UC1, 16UC1, 32FC1", parse, o.types))
        return 2;
    }
    else if (a == "--roll" && value)  // numbers the Config's validation then checks (checkOptions)
    {
      const auto parse = [](const std::string& r, double& v) { return number(r.c_str(), v); };
      if (!listOf(a.c_str(), argv[++i], "a number [rad]", parse, o.rolls))
        return 2;
    }
    else if (a == "--surface-band" && value)
    {
      if (!number(argv[++i], o.surface_band))
      {
        std::fprintf(stderr, "--surface-band: '%s' is not a number\n", argv[i]);
        return 2;
      }
    }
    else if (a == "--no-refine-floor")
      o.refine_floor = false;
    else if (a == "--markdown")
      o.markdown = true;
    else if (a == "--simd" && value)
    {
      o.simds = commaList(argv[++i]);
      o.simd_from_env = false;
    }
    else if (a == "--reference" && value)
    {
      o.references = commaList(argv[++i]);
      ReferencePaths paths;
      for (const std::string& r : o.references)
        if (!parseReference(r, paths))
        {
          std::fprintf(stderr, "--reference: '%s' is not none, all, or fast paths joined by '+' (labels, binning, "
                               "opening, portable)\n", r.c_str());
          return 2;
        }
    }
    else if (a == "--threads" && value)  // e.g. 1,2,4,8,16; the first is the speed-up's reference
    {
      const auto parse = [](const std::string& t, int& n) { return integerIn(t.c_str(), 1, 1024, n); };
      if (!listOf(a.c_str(), argv[++i], "a thread count 1..1024", parse, o.thread_counts))
        return 2;
    }
    else
    {
      std::fprintf(stderr, "usage: %s [--frames N] [--kernel K] [--projection horizontal|column] [--threads 1,2,...] "
                           "[--encodings 8UC1,16UC1,32FC1] [--simd native|avx512|avx2|sse4|scalar,...] "
                           "[--reference none|all|labels+binning+opening+portable,...] [--surface-band B] "
                           "[--roll RAD,...] [--no-refine-floor] [--markdown]\n", argv[0]);
      return a == "--help" || a == "-h" ? 0 : 2;
    }
  }
  if (!checkOptions(o, o.simd_from_env ? "KINECT_PIPELINE_SIMD" : "--simd"))
    return 2;
  for (const std::string& t : o.simds)
    try
    {
      restrictSimd(t);
    }
    catch (const std::invalid_argument& e)
    {
      std::fprintf(stderr, "%s: %s\n", o.simd_from_env ? "KINECT_PIPELINE_SIMD" : "--simd", e.what());
      return 2;
    }
  return -1;
}

struct Row
{
  std::string enc, simd, reference;
  double roll;
  int threads;
  double memcpy_ms, total, prepare, floor_fit, erode, classify, confidence;
  double allocs;
};

// One row of the table: `frames` frames of one encoding, thread count, SIMD target and set of reference paths.
Row measure(const Options& o, const Camera& cam, const cv::Mat& frame, double roll, int threads,
            const std::string& simd, const std::string& reference)
{
  restrictSimd(simd);
  ReferencePaths paths;
  parseReference(reference, paths);
  Pipeline pipe(cam, benchConfig(o, threads, roll), paths);
  FrameResult res;
  // Warm-up, with a pitch that changes every frame as on a Segway (the plane terms are recomputed).
  for (int i = 0; i < 30; ++i)
    pipe.process(frame, 0.01 * std::sin(i * 0.3), 0.0, res);
  cv::Mat copy(frame.size(), frame.type());
  const std::size_t bytes = frame.total() * frame.elemSize();
  std::vector<double> tm, tt, tp, tff, te, tc, tf;
  long allocs = 0;
  for (int i = 0; i < o.frames; ++i)
  {
    auto a = Clock::now();
    std::memcpy(copy.data, frame.data, bytes);
    tm.push_back(ms(a, Clock::now()));
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
  const int type = frame.type();
  const Encoding enc = type == CV_8UC1 ? Encoding::kMono8 : type == CV_16UC1 ? Encoding::kMono16 : Encoding::kFloat32;
  return {toString(enc), simd == "native" ? "native (" + simdTarget() + ")" : simdTarget(), reference, roll, threads,
          median(tm), median(tt), median(tp), median(tff), median(te), median(tc), median(tf),
          static_cast<double>(allocs) / o.frames};
}

// "0, 0.0087" (the rolls in the title line).
std::string rollList(const Options& o)
{
  std::string out;
  char number[32];
  for (const double roll : o.rolls)
  {
    std::snprintf(number, sizeof number, "%g", roll);
    out += (out.empty() ? "" : ", ") + std::string(number);
  }
  return out;
}

void printTable(const Options& o, const std::vector<Row>& rows)
{
  const std::string opening =
      o.kernel < 3 ? "no opening" : "opening " + std::to_string(o.kernel) + "x" + std::to_string(o.kernel) + " rect";
  std::printf("kinect_pipeline core benchmark: 512x424, %d frames each, %s, %s projection, surface_band %g, pitch "
              "changing every frame, roll %s rad\n",
              o.frames, opening.c_str(), o.projection.c_str(), o.surface_band, rollList(o).c_str());
  const bool roll_column = o.rolls.size() > 1;  // the roll of each row, where they differ
  if (o.markdown)
  {
    std::printf("| encoding | simd | threads | reference paths |%s memcpy [ms] | prepare | (floor fit) | erode | "
                "classify+scan | confidence | frame [ms] | frame / memcpy | floor fit / frame | speed-up vs 1 thread "
                "| allocations / frame |\n", roll_column ? " roll [rad] |" : "");
    std::printf("|---|---|---|---|%s---|---|---|---|---|---|---|---|---|---|---|\n", roll_column ? "---|" : "");
  }
  else
  {
    std::printf("%-6s %-15s %3s %-14s%s %9s %8s %9s %8s %9s %8s %9s %8s %9s %8s %7s\n", "enc", "simd", "thr",
                "reference", roll_column ? "     roll" : "", "memcpy", "prepare", "floor fit", "erode", "classify",
                "conf", "frame", "x memcpy", "fit/frame", "speedup", "allocs");
  }
  // Rows run encoding by encoding, then roll, thread count, target and reference paths: the speed-up is against the
  // same encoding, roll, target and paths at the first thread count.
  const std::size_t per_threads = o.simds.size() * o.references.size(), per_roll = o.thread_counts.size() * per_threads;
  for (std::size_t i = 0; i < rows.size(); ++i)
  {
    const Row& r = rows[i];
    const double speedup = rows[i - i % per_roll + i % per_threads].total / r.total;
    char roll[32] = "";
    if (roll_column)
      std::snprintf(roll, sizeof roll, o.markdown ? " %g |" : " %8g", r.roll);
    if (o.markdown)
      std::printf("| %s | %s | %d | %s |%s %.4f | %.4f | %.4f | %.4f | %.4f | %.4f | %.4f | %.1f | %.1f %% | %.2f | "
                  "%.1f |\n",
                  r.enc.c_str(), r.simd.c_str(), r.threads, r.reference.c_str(), roll, r.memcpy_ms, r.prepare,
                  r.floor_fit, r.erode, r.classify, r.confidence, r.total, r.total / r.memcpy_ms,
                  100.0 * r.floor_fit / r.total, speedup, r.allocs);
    else
      std::printf("%-6s %-15s %3d %-14s%s %9.4f %8.4f %9.4f %8.4f %9.4f %8.4f %9.4f %8.1f %8.1f%% %8.2f %7.1f\n",
                  r.enc.c_str(), r.simd.c_str(), r.threads, r.reference.c_str(), roll, r.memcpy_ms, r.prepare,
                  r.floor_fit, r.erode, r.classify, r.confidence, r.total, r.total / r.memcpy_ms,
                  100.0 * r.floor_fit / r.total, speedup, r.allocs);
  }
  std::printf("(times are medians in ms; 'x memcpy' = frame / memcpy of the same frame in the same run; the floor fit is "
              "part of prepare, and 'fit/frame' its share of the frame; 'reference': the fast paths replaced by their "
              "plain reference, none by default)\n");
}
}  // namespace

int main(int argc, char** argv)
{
  Options o;
  if (const int rc = parseOptions(argc, argv, o); rc >= 0)
    return rc;
  // The scene is rendered with OpenCV, whose own worker threads (TBB) would then spin on the CPUs for a while,
  // beside the frames' OpenMP threads: the pipeline uses no OpenCV threads, and the bench renders on one.
  cv::setNumThreads(0);
  const Camera cam = Camera::fromFov(512, 424, 1.2322, 1.0472);
  std::vector<cv::Mat> metres;  // the scene at each roll, with the sensor's noise
  for (const double roll : o.rolls)
  {
    Rendering rendering;
    renderScene(cam, kHeight, kPitch, roll, labScene(), rendering);
    metres.push_back(rendering.depth.clone());
    addKinectNoise(metres.back(), 1);
  }
  std::vector<Row> rows;
  for (const int type : o.types)
    for (std::size_t k = 0; k < o.rolls.size(); ++k)
    {
      const cv::Mat frame = encodeDepth(metres[k], type, 12.0);
      for (const int threads : o.thread_counts)
        for (const std::string& simd : o.simds)
          for (const std::string& reference : o.references)
            rows.push_back(measure(o, cam, frame, o.rolls[k], threads, simd, reference));
    }
  printTable(o, rows);
  return 0;
}
