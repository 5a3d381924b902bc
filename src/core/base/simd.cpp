// The SIMD target's names and its restriction (kinect_pipeline/simd.h) on Highway's run-time dispatch. The target
// in use is asked of the dispatch itself (a function compiled once per target, like every kernel), not inferred.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "base/simd.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "kinect_pipeline/simd.h"

#include <cstdint>
#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <utility>

#include <hwy/targets.h>

#include "base/simd.h"

HWY_BEFORE_NAMESPACE();
namespace kinect_pipeline
{
namespace detail
{
namespace HWY_NAMESPACE
{
std::int64_t dispatchedTarget() { return HWY_TARGET; }
}  // namespace HWY_NAMESPACE
}  // namespace detail
}  // namespace kinect_pipeline
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace kinect_pipeline
{
namespace detail
{
HWY_EXPORT(dispatchedTarget);
}  // namespace detail

namespace
{
// Our names of Highway's targets, best first. AVX3 is x86-64-v4's AVX-512 (F, BW, DQ, VL). SVE2_128 is SVE2 compiled
// for 128-bit vectors, which Highway picks on CPUs of that length (Neoverse N2 and V2: NVIDIA Grace, Graviton4);
// SVE2 and SVE take any length (SVE_256 is not built: cmake/highway.cmake). The plain C++ one is EMU128 (vectors of
// 16 bytes) or, under GCC before 12.3 (a GCC bug), SCALAR (vectors of one lane).
const std::pair<std::int64_t, const char*> kNames[] = {
    {HWY_AVX3, "avx512"}, {HWY_AVX2, "avx2"}, {HWY_SSE4, "sse4"},     {HWY_SVE2_128, "sve2_128"}, {HWY_SVE2, "sve2"},
    {HWY_SVE, "sve"},     {HWY_NEON, "neon"}, {HWY_EMU128, "scalar"}, {HWY_SCALAR, "scalar"}};

// The targets the core is built for that the CPU has, whatever the restriction.
std::int64_t cpuTargets()
{
  static const std::int64_t cpu = hwy::SupportedTargets() & HWY_TARGETS;  // before any restriction
  return cpu;
}

std::string joined(const std::vector<std::string>& names)
{
  std::string s;
  for (const std::string& n : names)
    s += (s.empty() ? "" : ", ") + n;
  return s;
}
}  // namespace

std::vector<std::string> simdTargets()
{
  std::vector<std::string> names;
  for (const auto& [bit, name] : kNames)
    if (cpuTargets() & bit)
      names.emplace_back(name);
  return names;
}

std::string simdTarget()
{
  detail::simdFromEnvironment();
  const std::int64_t now = HWY_DYNAMIC_DISPATCH(detail::dispatchedTarget)();
  for (const auto& [bit, name] : kNames)
    if (now == bit)
      return name;
  return hwy::TargetName(now);
}

// Highway's mask of supported targets is what restricts the dispatch here (SetSupportedTargetsForTest): with
// DisableTargets instead, the kernels of a benchmark run stayed on AVX-512 (Highway 1.0.3). simdTarget() asks the
// dispatch which target it runs, so a restriction that does not hold shows (kp_test::forEachSimdTarget checks it).
namespace
{
void applyTarget(const std::string& target)
{
  const std::int64_t cpu = cpuTargets();
  if (target == "native")
  {
    hwy::SetSupportedTargetsForTest(0);
    hwy::GetChosenTarget().Update(hwy::SupportedTargets());
    return;
  }
  for (const auto& [bit, name] : kNames)
    if (target == name && (cpu & bit))
    {
      hwy::SetSupportedTargetsForTest(bit);
      hwy::GetChosenTarget().Update(hwy::SupportedTargets());
      return;
    }
  throw std::invalid_argument("SIMD target '" + target + "': expected native or one this CPU has (" +
                              joined(simdTargets()) + ")");
}

// KINECT_PIPELINE_SIMD, applied once per process unless restrictSimd came first (an explicit call wins over the
// environment, whenever it is made); what was wrong with its value, until restrictSimd replaces it.
struct Environment
{
  std::mutex mutex;
  bool applied = false;
  std::string problem;
};
Environment& environment()
{
  static Environment e;
  return e;
}
}  // namespace

void restrictSimd(const std::string& target)
{
  applyTarget(target);  // throws for a bad name before the environment is set aside
  Environment& e = environment();
  std::lock_guard<std::mutex> lock(e.mutex);
  e.applied = true;
  e.problem.clear();
}

void detail::simdFromEnvironment()
{
  Environment& e = environment();
  std::lock_guard<std::mutex> lock(e.mutex);
  if (!e.applied)
  {
    e.applied = true;
    const char* env = std::getenv("KINECT_PIPELINE_SIMD");
    if (env != nullptr && *env != '\0')
      try
      {
        applyTarget(env);
      }
      catch (const std::invalid_argument& err)
      {
        e.problem = std::string("KINECT_PIPELINE_SIMD: ") + err.what();
      }
  }
  if (!e.problem.empty())
    throw std::invalid_argument(e.problem);
}
}  // namespace kinect_pipeline
#endif  // HWY_ONCE
