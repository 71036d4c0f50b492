#include "slam/features/opencv_threads.h"

#include <opencv2/core/utility.hpp>

namespace cslam {

void run_opencv_on_calling_threads() { cv::setNumThreads(1); }

}  // namespace cslam
