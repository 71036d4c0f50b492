# All third-party packages come from Debian 12 (see scripts/install-deps.sh).
find_package(Threads REQUIRED)
find_package(Eigen3 3.3 REQUIRED NO_MODULE)
find_package(OpenCV REQUIRED COMPONENTS core imgproc imgcodecs features2d calib3d)
find_package(Ceres REQUIRED)
# CHOLMOD's supernodal Cholesky (SuiteSparse, which Debian's Ceres is built on) factorises the
# block-sparse reduced camera system of large BAs (src/optimize/block_sparse_system.cpp).
find_path(CHOLMOD_INCLUDE_DIR cholmod.h PATH_SUFFIXES suitesparse REQUIRED)
find_library(CHOLMOD_LIBRARY cholmod REQUIRED)
add_library(cslam_cholmod INTERFACE)
target_include_directories(cslam_cholmod SYSTEM INTERFACE ${CHOLMOD_INCLUDE_DIR})
target_link_libraries(cslam_cholmod INTERFACE ${CHOLMOD_LIBRARY})
# Only the PCL components we use: 'io' would drag VTK and MPI in on Debian.
find_package(PCL REQUIRED COMPONENTS common filters kdtree search)
find_package(spdlog REQUIRED)
find_package(nlohmann_json 3 REQUIRED)
find_package(PkgConfig REQUIRED)
pkg_check_modules(ZSTD REQUIRED IMPORTED_TARGET libzstd)
find_package(Boost 1.74 REQUIRED)  # header-only: boost::container::flat_map (map point observations)
find_package(ZLIB REQUIRED)  # bounded PNG pre-check (src/codec/png_guard.cpp)
# JPEG straight to BGR (src/codec/jpeg_decode.cpp): OpenCV 4.6 decodes to RGB and swaps bytes.
pkg_check_modules(TURBOJPEG REQUIRED IMPORTED_TARGET libturbojpeg)
# 16-bit depth PNGs (src/codec/png16_decode.cpp): whole-buffer inflate, ~3.7x faster than zlib's on TUM depth.
pkg_check_modules(LIBDEFLATE REQUIRED IMPORTED_TARGET libdeflate)
# Inter-frame H.264 colour (src/codec/video_codec.cpp): libx264 and the H.264 decoder through
# Debian's libavcodec. gcc links --as-needed, so only programs using the video codec load it.
pkg_check_modules(LIBAVCODEC REQUIRED IMPORTED_TARGET libavcodec libavutil)
# Allocator of every program and test (cmake/CslamTargets.cmake): each frame allocates and frees
# hundreds of short-lived buffers (frame data, BA problems, match lists) across threads; glibc's
# malloc spent ~3 % of the SLAM's CPU in consolidation and page faults, tcmalloc's per-thread
# caches 3-8 % less CPU per frame in all (docs/performance.md, round 10), same results.
pkg_check_modules(TCMALLOC REQUIRED IMPORTED_TARGET libtcmalloc_minimal)
find_package(GTest REQUIRED)
