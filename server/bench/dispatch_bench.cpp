// cslam-bench-dispatch: the server's per-frame work in isolation: parse a serialized
// ClientMessage, decode both images (proto/adapter), submit to CollaborativeSystem (SLAM off).
// Reports wall time and process CPU time per frame (CPU time is less sensitive to other load).
#include <cstdio>
#include <ctime>
#include <iostream>

#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "core/stats.h"
#include "geometry/camera.h"
#include "io/tum_dataset.h"
#include "proto/adapter.h"
#include "system/collaborative_system.h"
#include "io/dataset_frame.h"

namespace {

double cpu_ms() {
  timespec ts{};
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
  return ts.tv_sec * 1e3 + ts.tv_nsec / 1e6;
}

int run(int argc, char** argv) {
  cslam::CliArgs cli("cslam-bench-dispatch", "Server decode + dispatch time per frame (parse, decode, submit).");
  cli.option("dataset", "TUM-layout folder", std::string(CSLAM_SHARED_DATA_DIR) + "/tum_fr1_rpy")
      .option("frames", "frames to use", "200")
      .option("rgb-codec", "raw | jpeg | png", "jpeg")
      .option("jpeg-quality", "JPEG quality", std::to_string(cslam::CodecOptions().jpeg_quality))
      .option("depth-codec", "raw | png | rvl | zstd", "zstd");
  if (!cli.parse(argc, argv)) return 0;
  const cslam::TumDataset ds = cslam::open_tum_dataset(cli.get("dataset"));
  const int n = std::min<int>(cli.get_int("frames"), int(ds.pairs.size()));
  cslam::CodecOptions codecs;
  codecs.rgb = cslam::parse_rgb_codec(cli.get("rgb-codec"));
  codecs.jpeg_quality = cli.get_int("jpeg-quality");
  codecs.depth = cslam::parse_depth_codec(cli.get("depth-codec"));
  std::vector<std::string> messages;
  std::size_t bytes = 0;
  cslam::ImageEncoder images(codecs);
  for (int i = 0; i < n; ++i) {
    const cslam::RgbdFrame f = cslam::load_dataset_frame(ds.pairs[std::size_t(i)], 1, std::uint64_t(i + 1));
    cslam::wire::ClientMessage m;
    cslam::wire::to_wire_frame(f, images, m.mutable_frame());
    messages.push_back(m.SerializeAsString());
    bytes += messages.back().size();
  }
  cslam::SystemConfig sc;
  sc.run_slam = false;
  sc.client_queue_capacity = std::size_t(n) + 1;
  cslam::CollaborativeSystem system(sc);
  cslam::ClientInfo info;
  info.id = 1;
  info.camera = cslam::camera_tum_fr1();
  system.add_client(info);
  std::vector<double> wall, cpu;
  for (const std::string& bytes_i : messages) {
    const double c0 = cpu_ms();
    const cslam::Stopwatch t;
    const cslam::wire::ClientMessage m = cslam::wire::parse_client_message(bytes_i.data(), bytes_i.size(), "bench");
    system.submit(cslam::wire::from_wire_frame(m.frame(), info.camera, "bench"));
    wall.push_back(t.ms());
    cpu.push_back(cpu_ms() - c0);
  }
  system.finish();
  const cslam::Summary w = cslam::summarize(wall), c = cslam::summarize(cpu);
  std::printf("%d frames, %s q%d + %s, %.1f KB/message\n", n, cslam::to_string(codecs.rgb), codecs.jpeg_quality,
              cslam::to_string(codecs.depth), bytes / 1e3 / n);
  std::printf("decode+dispatch wall ms: median %.2f  min %.2f  max %.2f  p95 %.2f\n", w.median, w.min, w.max, w.p95);
  std::printf("decode+dispatch CPU ms : median %.2f  min %.2f  max %.2f  p95 %.2f\n", c.median, c.min, c.max, c.p95);
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cslam::run_main("cslam-bench-dispatch", argc, argv, run); }
