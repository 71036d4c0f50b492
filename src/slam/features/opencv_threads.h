#pragma once
// OpenCV's own thread pool in programs that already run one thread per pipeline stage.
namespace cslam {

// Makes OpenCV run every call on the calling thread (cv::setNumThreads(1)). The SLAM programs
// give each stage (tracking, local mapping, loop closing, fusion, per-client workers) its own
// thread, so splitting a resize or a blur over OpenCV's pool gains nothing on the cores, while
// the pool's idle workers spin between calls: on fr1/rpy (one client, 2 cores) 1.4 % of the
// process' CPU in the pool and about as much again in the kernel's sched_yield. Results are
// unchanged (OpenCV's parallel loops split work, not arithmetic). Call once at the start of main.
void run_opencv_on_calling_threads();

}  // namespace cslam
