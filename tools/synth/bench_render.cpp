// cslam-synth-bench: render speed of the synthetic renderer (frames/s) along a demo trajectory.
#include <time.h>

#include <algorithm>
#include <cstdio>
#include <vector>

#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "core/stats.h"
#include "support/synth/renderer.h"
#include "support/synth/synth_config.h"
#include "support/synth/trajectory_planner.h"

using namespace cslam;
using namespace cslam::synth;

namespace {

int run(int argc, char** argv) {
  CliArgs args("cslam-synth-bench", "Renders frames of the demo scene along robot 1's path and prints frames/s.");
  args.option("frames", "frames to time (after 5 warm-up frames)", "150")
      .option("width", "image width", "640")
      .option("height", "image height", "480")
      .option("threads", "render threads per frame", "1")
      .flag("noise", "enable the degradations (without motion blur: blur renders several times)")
      .flag("blur", "with --noise: motion blur too");
  if (!args.parse(argc, argv)) return 0;
  SynthConfig c = synth_preset("demo");
  c.camera = synthetic_camera(args.get_int("width"), args.get_int("height"));
  c.render.threads = args.get_int("threads");
  c.render.degradation.enabled = args.flag_set("noise");
  if (!args.flag_set("blur")) c.render.degradation.blur_samples = 1;
  Stopwatch setup;
  const Scene scene = make_scene(c.scene);
  const double scene_ms = setup.ms();
  const TrajectoryPlan plan = plan_trajectories(scene, c.trajectory);
  const Renderer renderer(scene, c.camera, c.render);
  const Trajectory& traj = plan.robots[0].trajectory;
  const int n = args.get_int("frames");
  if (n < 1) throw ConfigError("--frames must be >= 1");
  std::vector<double> ms, cpu;
  for (int i = -5; i < n; ++i) {
    const size_t k = static_cast<size_t>(std::max(i, 0) * 2) % traj.size();
    Stopwatch sw;
    const double c0 = thread_cpu_ms();
    const RenderedFrame f = renderer.render_moving(traj[k > 0 ? k - 1 : 0].T_world_cam, traj[k].T_world_cam, k);
    if (i >= 0) {
      ms.push_back(sw.ms());
      cpu.push_back(thread_cpu_ms() - c0);
    }
    if (f.bgr.empty()) return 1;
  }
  std::sort(ms.begin(), ms.end());
  std::sort(cpu.begin(), cpu.end());
  const double median = ms[ms.size() / 2];
  std::printf("scene: %zu faces, %zu textures, made in %.0f ms\n", scene.faces.size(), scene.textures.size(), scene_ms);
  std::printf(
      "render %dx%d, %d thread(s), noise %s: %d frames, ms/frame median %.2f min %.2f max %.2f -> %.1f frames/s "
      "(median), %.1f-%.1f\n",
      c.camera.width, c.camera.height, c.render.threads, c.render.degradation.enabled ? "on" : "off", n, median,
      ms.front(), ms.back(), 1000.0 / median, 1000.0 / ms.back(), 1000.0 / ms.front());
  if (c.render.threads == 1)
    std::printf(
        "CPU time of the rendering thread: ms/frame median %.2f min %.2f max %.2f -> %.1f frames/s per core (median), "
        "%.1f-%.1f\n",
        cpu[cpu.size() / 2], cpu.front(), cpu.back(), 1000.0 / cpu[cpu.size() / 2], 1000.0 / cpu.back(),
        1000.0 / cpu.front());
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-synth-bench", argc, argv, run); }
