// cslam-synth: renders RGB-D sequences of a procedural indoor scene for K robots in the TUM layout.
#include <cstdio>
#include <iostream>
#include <sstream>

#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "support/synth/dataset_writer.h"

using namespace cslam;
using namespace cslam::synth;

namespace {

// "8x6x3" -> width, depth, height.
void parse_room(const std::string& text, SceneConfig& scene) {
  double w = 0, d = 0, h = 0;
  char x1 = 0, x2 = 0, extra = 0;
  std::istringstream in(text);
  if (!(in >> w >> x1 >> d >> x2 >> h) || x1 != 'x' || x2 != 'x' || (in >> extra))
    throw ConfigError("cslam-synth: --room expects WxDxH in metres, e.g. 8x6x3, got '" + text + "'");
  scene.width = w;
  scene.depth = d;
  scene.height = h;
}

int run(int argc, char** argv) {
  CliArgs args(
      "cslam-synth",
      "Renders RGB-D sequences of a procedurally generated room for K robots in the TUM RGB-D layout:\n"
      "OUT/robot_<k>/{rgb,depth,rgb.txt,depth.txt,groundtruth.txt,camera.yaml}, OUT/scene.ply, OUT/scene.json.\n"
      "Options left empty take the preset's value.");
  args.option("out", "output folder OUT (must not exist unless --force)")
      .option("preset", "demo (3 robots x 300 frames, 640x480, loop) | test-small (2 x 60, 320x240)", "demo")
      .option("robots", "number of robots K", "")
      .option("frames", "frames per robot (30 Hz)", "")
      .option("seed", "scene seed (same seed -> identical files)", "")
      .option("width", "image width", "")
      .option("height", "image height", "")
      .option("room", "room size WxDxH in metres, e.g. 8x6x3", "")
      .option("furniture", "number of boxes and cylinders", "")
      .option("overlap", "share of each robot's path that the next robot retraces, [0, 1)", "")
      .option("threads", "frames rendered in parallel", "2")
      .option("ply-spacing", "spacing of the scene.ply surface samples, metres", "0.01")
      .option("log-level", "trace, debug, info, warn, error, off", "info")
      .flag("noise", "realistic degradations: depth noise ~ z^2, no depth at grazing angles, image noise, motion blur")
      .flag("loop", "robot 1 drives a closed loop back to its start (needs >= ~270 frames)")
      .flag("no-loop", "no loop (robot 1 follows an arc like the others)")
      .flag("single", "single-robot mode (one robot, with a loop unless --no-loop)")
      .flag("whole", "one long sequence OUT/whole/ visiting every robot's path in turn (for cslam-eval split)")
      .flag("repeat-texture", "copy one poster-sized texture patch onto two different walls (place-recognition trap)")
      .option("shared-poster",
              "put a poster generated from this seed (not the room's) every ~2 m along both long walls: rooms of\n"
              "      different --seed with the same --shared-poster share it (cross-room place-recognition trap)",
              "")
      .flag("force", "replace OUT if it exists");
  if (!args.parse(argc, argv)) return 0;
  set_log_level(args.get("log-level"));
  SynthConfig c = synth_preset(args.get("preset"));
  auto given = [&](const char* name) { return !args.get(name).empty(); };
  if (given("robots")) c.trajectory.robots = args.get_int("robots");
  if (given("frames")) c.trajectory.frames = args.get_int("frames");
  if (given("seed")) {
    const std::string text = args.get("seed");
    if (text.find_first_not_of("0123456789") != std::string::npos || text.size() > 19)
      throw ConfigError("cslam-synth: --seed expects a non-negative integer, got '" + text + "'");
    c.scene.seed = static_cast<std::uint64_t>(std::stoull(text));
  }
  if (given("width") || given("height"))
    c.camera = synthetic_camera(given("width") ? args.get_int("width") : c.camera.width,
                                given("height") ? args.get_int("height") : c.camera.height);
  if (given("room")) parse_room(args.get("room"), c.scene);
  if (given("furniture")) c.scene.furniture = args.get_int("furniture");
  if (given("overlap")) c.trajectory.overlap = args.get_double("overlap");
  if (args.flag_set("single")) {
    c.trajectory.robots = 1;
    c.trajectory.loop = true;
  }
  if (args.flag_set("loop")) c.trajectory.loop = true;
  if (args.flag_set("no-loop")) c.trajectory.loop = false;
  c.render.degradation.enabled = args.flag_set("noise");
  c.scene.repeat_texture = args.flag_set("repeat-texture");
  if (given("shared-poster")) {
    const std::string text = args.get("shared-poster");
    if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos || text.size() > 19 ||
        std::stoull(text) == 0)
      throw ConfigError("cslam-synth: --shared-poster expects a positive integer seed, got '" + text + "'");
    c.scene.shared_poster_seed = static_cast<std::uint64_t>(std::stoull(text));
  }
  c.output.out_dir = args.get("out");
  c.output.whole = args.flag_set("whole");
  c.output.overwrite = args.flag_set("force");
  c.output.threads = args.get_int("threads");
  c.output.ply_spacing = args.get_double("ply-spacing");
  if (c.output.threads < 1) throw ConfigError("cslam-synth: --threads must be >= 1");

  auto log = logger("synth");
  log->info("preset {}: {} robot(s) x {} frames, {}x{}, room {}x{}x{} m, {} furniture, seed {}, loop {}, noise {}",
            c.preset, c.trajectory.robots, c.trajectory.frames, c.camera.width, c.camera.height, c.scene.width,
            c.scene.depth, c.scene.height, c.scene.furniture, c.scene.seed, c.trajectory.loop ? "on" : "off",
            c.render.degradation.enabled ? "on" : "off");
  const DatasetResult r = generate_dataset(c);
  log->info("wrote {} frames in {} sequence(s), {} surface points to {} in {:.1f} s", r.frames, r.sequences.size(),
            r.surface_points, r.out_dir, r.seconds);
  for (const auto& s : r.sequences) std::cout << s << "\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-synth", argc, argv, run); }
