// Which SIMD target the core's kernels run: the best one the CPU has, or one named by the user (benchmarks and
// tests compare targets side by side on one machine). Design notes: docs/core_design.md ("SIMD kernels and their
// references").
#pragma once

#include <string>
#include <vector>

namespace kinect_pipeline
{
/**
 * The targets the kernels are built for that this CPU can run, best first, by name: "avx512", "avx2", "sse4",
 * "scalar" on x86-64 ("sve2_128" where the CPU's SVE2 vectors are 128 bits long, "sve2", "sve", "neon", "scalar"
 * on aarch64). "scalar" runs everywhere: Highway's emulated vectors in plain C++, at the architecture's
 * baseline instruction set.
 */
std::vector<std::string> simdTargets();

/** The target the kernels run now (one of simdTargets()). */
std::string simdTarget();

/**
 * Restricts the kernels to one target for the whole process ("native": the best the CPU has, the default).
 * The environment variable KINECT_PIPELINE_SIMD does the same for a process from its first Pipeline (or
 * simdTarget()) on, unless this was called first: a call wins over the variable, made before or after it took
 * effect, and a good name lifts a bad value's refusal. Call it between frames, not while another thread runs one
 * (the frame then mixes targets: the same bits, but Highway's own target mask is not meant to change under a
 * running dispatch).
 * @throws std::invalid_argument naming the target where it is not one of simdTargets() or "native"
 */
void restrictSimd(const std::string& target);
}  // namespace kinect_pipeline
