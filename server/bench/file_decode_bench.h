#pragma once
// Part of cslam-bench-codec: time per image of decoding a dataset's own files (colour JPEG/PNG,
// 16-bit depth PNG) by each decoding path cslam has, and whether each path's pixels equal the
// reference path's (the first of its kind, cv::imread as load_rgbd used it). Depth: cv::imread,
// load_depth_image (libdeflate, codec/png16_decode.h), cv::imdecode and decode_png16_gray from
// memory (the decoders alone), and the wire's PNG decoder.
#include "io/tum_dataset.h"

namespace cslam {

struct FileDecodeBenchOptions {
  int files = 100;  // the first `files` colour and depth images of the dataset
  int repeat = 3;   // passes over them (each image timed once per pass)
};

// Prints one table (median and min-max thread-CPU ms per image, over files x repeat samples).
void run_file_decode_bench(const TumDataset& ds, const FileDecodeBenchOptions& options);

}  // namespace cslam
