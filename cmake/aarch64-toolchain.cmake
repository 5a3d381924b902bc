# CMake toolchain file: aarch64-linux-gnu (64-bit Arm Linux) from an x86-64 Debian/Ubuntu host.
#   cmake -S test/cross -B build/aarch64 -DCMAKE_TOOLCHAIN_FILE=cmake/aarch64-toolchain.cmake \
#         [-DKP_AARCH64_SYSROOT=/abs/path/to/extracted/arm64/debs]
# The compiler is Debian's cross GCC (g++-aarch64-linux-gnu): its C library, libstdc++ and libgomp live in
# /usr/aarch64-linux-gnu. The target's other libraries are found
#   - in KP_AARCH64_SYSROOT (or $ENV{KP_AARCH64_SYSROOT}), a folder where arm64 .debs were unpacked
#     (dpkg-deb -x; scripts/cross_aarch64.sh makes one in build/aarch64-sysroot), and
#   - in the multiarch paths of this machine (/usr/lib/aarch64-linux-gnu, /usr/include/aarch64-linux-gnu),
#     for packages installed with dpkg --add-architecture arm64 && apt-get install libfoo-dev:arm64.
# Programs built with it run under qemu-user: CMAKE_CROSSCOMPILING_EMULATOR (used by ctest) is set to
# qemu-aarch64[-static] -L /usr/aarch64-linux-gnu -E LD_LIBRARY_PATH=<the sysroot's library folders>.
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(KP_CROSS_TRIPLE aarch64-linux-gnu)
set(CMAKE_LIBRARY_ARCHITECTURE ${KP_CROSS_TRIPLE})

find_program(KP_CROSS_CXX ${KP_CROSS_TRIPLE}-g++ REQUIRED)
find_program(KP_CROSS_CC ${KP_CROSS_TRIPLE}-gcc REQUIRED)
set(CMAKE_C_COMPILER ${KP_CROSS_CC})
set(CMAKE_CXX_COMPILER ${KP_CROSS_CXX})

# try_compile projects re-read this file without the command line's -D: pass the sysroot on.
if(NOT DEFINED KP_AARCH64_SYSROOT AND DEFINED ENV{KP_AARCH64_SYSROOT})
  set(KP_AARCH64_SYSROOT $ENV{KP_AARCH64_SYSROOT})
endif()
list(APPEND CMAKE_TRY_COMPILE_PLATFORM_VARIABLES KP_AARCH64_SYSROOT)

# Roots searched for the target's libraries, headers and CMake packages (OpenCVConfig.cmake), in this order.
set(CMAKE_FIND_ROOT_PATH /usr/${KP_CROSS_TRIPLE})
set(KP_CROSS_LIBDIRS /usr/${KP_CROSS_TRIPLE}/lib)
if(KP_AARCH64_SYSROOT)
  list(APPEND CMAKE_FIND_ROOT_PATH ${KP_AARCH64_SYSROOT})
  # usr/lib too: packages that are not Multi-Arch: same put their libraries there (libarmadillo, libogdi, hdf4).
  list(APPEND KP_CROSS_LIBDIRS ${KP_AARCH64_SYSROOT}/usr/lib/${KP_CROSS_TRIPLE} ${KP_AARCH64_SYSROOT}/lib/${KP_CROSS_TRIPLE}
       ${KP_AARCH64_SYSROOT}/usr/lib)
endif()
# Multiarch: "/" with CMAKE_LIBRARY_ARCHITECTURE searches /usr/lib/aarch64-linux-gnu (never x86_64-linux-gnu).
list(APPEND CMAKE_FIND_ROOT_PATH /)
list(APPEND KP_CROSS_LIBDIRS /usr/lib/${KP_CROSS_TRIPLE} /lib/${KP_CROSS_TRIPLE})
set(CMAKE_FIND_ROOT_PATH_MODE_PROGRAM NEVER)
set(CMAKE_FIND_ROOT_PATH_MODE_LIBRARY ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_INCLUDE ONLY)
set(CMAKE_FIND_ROOT_PATH_MODE_PACKAGE ONLY)

# The linker must see the libraries' own dependencies (libopencv_imgcodecs -> libgdal -> ...), which are not
# on the link line.
string(REPLACE ";" ":" KP_CROSS_RPATH_LINK "${KP_CROSS_LIBDIRS}")
set(CMAKE_EXE_LINKER_FLAGS_INIT "-Wl,-rpath-link,${KP_CROSS_RPATH_LINK}")
set(CMAKE_SHARED_LINKER_FLAGS_INIT "-Wl,-rpath-link,${KP_CROSS_RPATH_LINK}")
set(CMAKE_MODULE_LINKER_FLAGS_INIT "-Wl,-rpath-link,${KP_CROSS_RPATH_LINK}")

# Running the target's programs on this machine. LD_LIBRARY_PATH, not an RPATH: DT_RUNPATH is not applied to
# the dependencies of dependencies. qemu's -L prefix is tried first on every path the program opens, then the
# path itself, so the sysroot's absolute paths work as they are.
find_program(KP_QEMU_AARCH64 NAMES qemu-aarch64-static qemu-aarch64)
if(KP_QEMU_AARCH64)
  list(REMOVE_ITEM KP_CROSS_LIBDIRS /usr/${KP_CROSS_TRIPLE}/lib)
  string(REPLACE ";" ":" KP_CROSS_LD_LIBRARY_PATH "${KP_CROSS_LIBDIRS}")
  set(CMAKE_CROSSCOMPILING_EMULATOR ${KP_QEMU_AARCH64} -L /usr/${KP_CROSS_TRIPLE}
      -E LD_LIBRARY_PATH=${KP_CROSS_LD_LIBRARY_PATH})
endif()
