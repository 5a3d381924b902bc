# The core's SIMD settings, one place for the catkin build and the sanitizer, fuzzer and cross builds:
# Google Highway (Debian's libhwy-dev) compiles the kernels once per target and picks one at run time
# (src/core/base/simd.h): scalar, SSE4, AVX2 and AVX-512 on x86-64 (SSSE3 would only add build time), NEON and
# SVE on aarch64. -ffp-contract=off: no target fuses a multiply and an add, so every target gives the same bits.
#   kp_use_highway(<target> <PRIVATE|PUBLIC>)
function(kp_use_highway target scope)
  find_path(KP_HWY_INCLUDE hwy/highway.h REQUIRED)
  find_library(KP_HWY_LIBRARY hwy REQUIRED)
  target_include_directories(${target} SYSTEM ${scope} ${KP_HWY_INCLUDE})
  target_link_libraries(${target} ${scope} ${KP_HWY_LIBRARY})
  target_compile_definitions(${target} ${scope} HWY_COMPILE_ALL_ATTAINABLE HWY_DISABLED_TARGETS=HWY_SSSE3)
  target_compile_options(${target} ${scope} -ffp-contract=off)
endfunction()
