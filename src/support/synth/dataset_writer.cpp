#include "support/synth/dataset_writer.h"

#include <unistd.h>

#include <atomic>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <mutex>
#include <thread>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "codec/codec_plugins.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "geometry/camera_io.h"
#include "support/synth/random.h"
#include "support/synth/surface_sampling.h"

namespace fs = std::filesystem;

namespace cslam::synth {
namespace {

std::string stamp(double t) {
  char buf[64];
  std::snprintf(buf, sizeof(buf), "%.6f", t);
  return buf;
}

void write_list(const std::string& path, const std::string& what, const std::string& folder, const Trajectory& traj) {
  std::ofstream out(path);
  if (!out) throw InputError(path, "cannot create file");
  out << "# " << what << "\n# file: 'cslam-synth'\n# timestamp filename\n";
  for (const auto& p : traj) out << stamp(p.timestamp) << " " << folder << "/" << stamp(p.timestamp) << ".png\n";
  if (!out) throw InputError(path, "write failed");
}

nlohmann::json vec(const Eigen::Vector3d& v) { return {v.x(), v.y(), v.z()}; }

nlohmann::json describe(const Scene& scene, const TrajectoryPlan& plan, const SynthConfig& c,
                        const std::vector<std::string>& seqs) {
  const SceneConfig& s = c.scene;
  const TrajectoryConfig& t = c.trajectory;
  const Degradation& d = c.render.degradation;
  nlohmann::json j;
  j["generator"] = "cslam-synth 1";
  j["preset"] = c.preset;
  j["seed"] = s.seed;
  j["scene"] = {{"width", s.width},
                {"depth", s.depth},
                {"height", s.height},
                {"furniture", s.furniture},
                {"cylinder_fraction", s.cylinder_fraction},
                {"cylinder_sides", s.cylinder_sides},
                {"texel_size", s.texel_size},
                {"walkway_margin", s.walkway_margin},
                {"furniture_clearance", s.furniture_clearance},
                {"repeat_texture", s.repeat_texture},
                {"shared_poster_seed", s.shared_poster_seed},
                {"ambient", s.ambient}};
  j["walkway"] = {
      {"center", {scene.walkway.center.x(), scene.walkway.center.y()}}, {"a", scene.walkway.a}, {"b", scene.walkway.b}};
  for (const auto& f : scene.furniture)
    j["furniture"].push_back({{"kind", f.kind == Furniture::Kind::Box ? "box" : "cylinder"},
                              {"center", {f.center.x(), f.center.y()}},
                              {"half_x", f.half_x},
                              {"half_y", f.half_y},
                              {"radius", f.radius},
                              {"height", f.height}});
  for (const auto& c : scene.shared_posters) j["shared_posters"].push_back({c.x(), c.y(), c.z()});
  for (const auto& r : scene.repeated_patches)
    j["repeated_patches"].push_back({{"face_a", scene.faces[r.face_a].name},
                                     {"face_b", scene.faces[r.face_b].name},
                                     {"center_a", vec(r.center_a)},
                                     {"center_b", vec(r.center_b)},
                                     {"size", {r.size_u, r.size_v}}});
  for (const auto& l : scene.lights) j["lights"].push_back({{"position", vec(l.position)}, {"intensity", l.intensity}});
  j["trajectory"] = {{"robots", t.robots},
                     {"frames", t.frames},
                     {"rate_hz", t.rate_hz},
                     {"start_time", t.start_time},
                     {"loop", t.loop},
                     {"overlap", t.overlap},
                     {"speed", t.speed},
                     {"max_step", t.max_step},
                     {"max_rotation_deg", t.max_rotation_deg},
                     {"min_height", t.min_height},
                     {"max_height", t.max_height},
                     {"ramp_fraction", t.ramp_fraction}};
  for (size_t k = 0; k < plan.robots.size(); ++k) {
    const auto& r = plan.robots[k];
    j["robots"].push_back({{"robot", k + 1},
                           {"kind", r.kind},
                           {"phi_start", r.phi_start},
                           {"phi_end", r.phi_end},
                           {"radius", r.radius},
                           {"base_height", r.base_height},
                           {"frames", r.trajectory.size()}});
  }
  j["render"] = {{"min_depth", c.render.min_depth},          {"max_depth", c.render.max_depth},
                 {"near_clip", c.render.near_clip},          {"noise", d.enabled},
                 {"depth_noise_coeff", d.depth_noise_coeff}, {"grazing_angle_deg", d.grazing_angle_deg},
                 {"image_noise_sigma", d.image_noise_sigma}, {"blur_samples", d.blur_samples},
                 {"blur_exposure", d.blur_exposure}};
  const PinholeCamera& cam = c.camera;
  j["camera"] = {{"fx", cam.fx},
                 {"fy", cam.fy},
                 {"cx", cam.cx},
                 {"cy", cam.cy},
                 {"width", cam.width},
                 {"height", cam.height},
                 {"depth_factor", cam.depth_factor}};
  j["output"] = {{"whole", c.output.whole}, {"ply_spacing", c.output.ply_spacing}, {"sequences", seqs}};
  return j;
}

}  // namespace

void write_sequence(const std::string& dir, const Renderer& renderer, const Trajectory& trajectory,
                    std::uint64_t noise_seed, int threads, int png_compression) {
  if (threads < 1) throw ConfigError("synth: threads must be >= 1");
  if (png_compression < 0 || png_compression > 9) throw ConfigError("synth: PNG compression must be 0-9");
  std::error_code ec;
  fs::create_directories(fs::path(dir) / "rgb", ec);
  if (!ec) fs::create_directories(fs::path(dir) / "depth", ec);
  if (ec) throw InputError(dir, "cannot create folder: " + ec.message());
  // Huffman-only zlib is faster and smaller than the default strategy on noisy texture; depth
  // images (smooth) compress better with the default strategy.
  const std::vector<int> png_rgb{cv::IMWRITE_PNG_COMPRESSION, png_compression, cv::IMWRITE_PNG_STRATEGY,
                                 cv::IMWRITE_PNG_STRATEGY_HUFFMAN_ONLY};
  const std::vector<int> png_depth{cv::IMWRITE_PNG_COMPRESSION, png_compression};
  std::atomic<size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr error;
  std::mutex error_mutex;
  auto worker = [&] {
    try {
      for (size_t i = next++; i < trajectory.size() && !failed; i = next++) {
        const SE3& prev = trajectory[i > 0 ? i - 1 : 0].T_world_cam;
        const RenderedFrame f = renderer.render_moving(prev, trajectory[i].T_world_cam, derive_seed(noise_seed, i));
        const std::string name = stamp(trajectory[i].timestamp) + ".png";
        const std::string rgb_path = dir + "/rgb/" + name, depth_path = dir + "/depth/" + name;
        if (!image_io().imwrite(rgb_path, f.bgr, png_rgb)) throw InputError(rgb_path, "cannot write image");
        if (!image_io().imwrite(depth_path, f.depth, png_depth)) throw InputError(depth_path, "cannot write image");
      }
    } catch (...) {
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!error) error = std::current_exception();
      failed = true;
    }
  };
  std::vector<std::thread> workers;
  for (int k = 1; k < threads; ++k) workers.emplace_back(worker);
  worker();
  for (auto& w : workers) w.join();
  if (error) std::rethrow_exception(error);
  write_list(dir + "/rgb.txt", "color images", "rgb", trajectory);
  write_list(dir + "/depth.txt", "depth maps", "depth", trajectory);
  write_tum_trajectory(dir + "/groundtruth.txt", trajectory, "ground truth trajectory (cslam-synth)");
  save_camera_file(renderer.camera(), dir + "/camera.yaml");
}

DatasetResult write_dataset(const Scene& scene, const TrajectoryPlan& plan, const SynthConfig& config) {
  Stopwatch clock;
  const OutputConfig& o = config.output;
  if (o.out_dir.empty()) throw ConfigError("synth: no output folder given");
  fs::path out = fs::path(o.out_dir);
  if (out.filename().empty()) out = out.parent_path();  // "dir/" -> "dir"
  if (fs::exists(out) && !o.overwrite)
    throw InputError(out.string(), "output folder already exists (use --force to replace it)");
  const fs::path tmp = out.string() + ".tmp-" + std::to_string(::getpid());
  std::error_code ec;
  fs::remove_all(tmp, ec);
  fs::create_directories(tmp, ec);
  if (ec) throw InputError(out.string(), "cannot create output folder: " + ec.message());
  DatasetResult result;
  result.out_dir = out.string();
  try {
    Renderer renderer(scene, config.camera, config.render);
    const std::uint64_t seed = derive_seed(config.scene.seed, 3);
    std::vector<std::string> names;
    if (o.whole) {
      const Trajectory whole = make_whole_sequence(plan, config.trajectory);
      write_sequence((tmp / "whole").string(), renderer, whole, derive_seed(seed, 0), o.threads, o.png_compression);
      names.push_back("whole");
      result.frames += static_cast<int>(whole.size());
    } else {
      for (size_t k = 0; k < plan.robots.size(); ++k) {
        const std::string name = "robot_" + std::to_string(k + 1);
        write_sequence((tmp / name).string(), renderer, plan.robots[k].trajectory, derive_seed(seed, k + 1), o.threads,
                       o.png_compression);
        names.push_back(name);
        result.frames += static_cast<int>(plan.robots[k].trajectory.size());
      }
    }
    const SurfacePoints cloud = sample_surface_points(scene, o.ply_spacing);
    write_ply((tmp / "scene.ply").string(), cloud);
    result.surface_points = cloud.size();
    {
      const std::string path = (tmp / "scene.json").string();
      std::ofstream js(path);
      js << describe(scene, plan, config, names).dump(2) << "\n";
      if (!js) throw InputError(path, "write failed");
    }
    if (fs::exists(out)) fs::remove_all(out);
    fs::rename(tmp, out, ec);
    if (ec) throw InputError(out.string(), "cannot rename " + tmp.string() + ": " + ec.message());
    for (const auto& n : names) result.sequences.push_back((out / n).string());
  } catch (...) {
    fs::remove_all(tmp, ec);  // never leave a half-written dataset behind
    throw;
  }
  result.seconds = clock.ms() / 1000.0;
  return result;
}

DatasetResult generate_dataset(const SynthConfig& config) {
  const Scene scene = make_scene(config.scene);
  const TrajectoryPlan plan = plan_trajectories(scene, config.trajectory);
  return write_dataset(scene, plan, config);
}

}  // namespace cslam::synth
