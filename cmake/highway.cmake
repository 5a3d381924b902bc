# The core's SIMD settings, one place for the catkin build and the sanitizer, fuzzer and cross builds:
# Google Highway (Debian's libhwy-dev) compiles the kernels once per target and picks one at run time
# (src/core/base/simd.h): scalar, SSE4, AVX2 and AVX-512 on x86-64 (SSSE3 would only add build time), NEON, SVE,
# SVE2 and SVE2_128 (SVE2 on CPUs of 128-bit vectors) on aarch64. Not SVE_256 (SVE on CPUs of 256-bit vectors):
# under qemu at that length its 8-bit row split flagged other pixels for the rescue than the plain loops (3 pixels
# of PipelineEdge.EveryTargetGivesThePlainLoopsFrame's 100-pixel-wide frame), where the SVE target at the same
# length gives the same bits; such CPUs run SVE. -ffp-contract=off: no target fuses a multiply and an add, so every
# target gives the same bits.
#   kp_use_highway(<target> <PRIVATE|PUBLIC>)
function(kp_use_highway target scope)
  find_path(KP_HWY_INCLUDE hwy/highway.h REQUIRED)
  find_library(KP_HWY_LIBRARY hwy REQUIRED)
  target_include_directories(${target} SYSTEM ${scope} ${KP_HWY_INCLUDE})
  target_link_libraries(${target} ${scope} ${KP_HWY_LIBRARY})
  target_compile_definitions(${target} ${scope} HWY_COMPILE_ALL_ATTAINABLE
                             "HWY_DISABLED_TARGETS=(HWY_SSSE3|HWY_SVE_256)")
  target_compile_options(${target} ${scope} -ffp-contract=off)
endfunction()
