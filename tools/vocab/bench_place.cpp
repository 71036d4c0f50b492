// cslam-bench-place: place-recognition quality of the vocabulary + keyframe database.
//  1. Real sequence: database from every n-th frame of the first half, queries from the second
//     half that look at the same place as some keyframe (ground-truth viewing-direction angle
//     and position thresholds); reports recall@1 and precision of the top candidate.
//  2. Synthetic: two robots crossing the same place on a procedural planar scene; checks that the
//     keyframe of robot A at the crossing ranks first for robot B's crossing frame.
#include <cmath>
#include <cstdio>
#include <iostream>

#include "slam/bow/keyframe_database.h"
#include "slam/bow/vocabulary.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/stopwatch.h"
#include "slam/features/orb_extractor.h"
#include "slam/features/procedural_image.h"
#include "geometry/camera.h"
#include "image_sources.h"
#include "io/dataset_camera.h"
#include "io/tum_dataset.h"

using namespace cslam;

namespace {

const SE3* pose_at(const Trajectory& gt, double t, double max_dt = 0.02) {
  auto it = std::lower_bound(gt.begin(), gt.end(), t, [](const StampedPose& p, double v) { return p.timestamp < v; });
  const StampedPose* best = nullptr;
  if (it != gt.end()) best = &*it;
  if (it != gt.begin() && (!best || std::abs(std::prev(it)->timestamp - t) < std::abs(best->timestamp - t)))
    best = &*std::prev(it);
  if (!best || std::abs(best->timestamp - t) > max_dt) return nullptr;
  return &best->T_world_cam;
}

double view_angle_deg(const SE3& a, const SE3& b) {
  const Eigen::Vector3d za = a.R().col(2), zb = b.R().col(2);
  return std::acos(std::clamp(za.dot(zb), -1.0, 1.0)) * 180.0 / M_PI;
}

struct Outcome {
  int queries = 0, with_true_match = 0, answered = 0, correct_top1 = 0, correct_top1_with_match = 0;
};

void print_outcome(const char* name, const Outcome& o) {
  std::printf(
      "%-28s queries %d, with a true match %d, recall@1 %.3f (%d/%d), precision of top candidate %.3f (%d/%d)\n", name,
      o.queries, o.with_true_match, o.with_true_match ? double(o.correct_top1_with_match) / o.with_true_match : 0.0,
      o.correct_top1_with_match, o.with_true_match, o.answered ? double(o.correct_top1) / o.answered : 0.0,
      o.correct_top1, o.answered);
}

struct PosedImage {
  std::string path;
  SE3 T_world_cam;
};

// Frames of a TUM dataset with a ground-truth pose, every `every`-th of [first, last).
std::vector<PosedImage> posed_frames(const TumDataset& ds, const Trajectory& gt, int first, int last, int every) {
  std::vector<PosedImage> out;
  for (int i = first; i < last; i += every)
    if (const SE3* T = pose_at(gt, ds.rgb[i].timestamp)) out.push_back({ds.rgb[i].path, *T});
  return out;
}

PinholeCamera camera_of(const std::string& root) { return dataset_camera(root).camera; }

Trajectory groundtruth_of(const TumDataset& ds, const std::string& root) {
  if (!ds.groundtruth) throw InputError(root, "no groundtruth.txt");
  Trajectory gt = *ds.groundtruth;
  sort_by_time(gt);
  return gt;
}

// Database from `keyframes` (client 1), queries from `queries`; prints recall@1 and precision.
void evaluate(const std::vector<PosedImage>& keyframes, const PinholeCamera& kf_camera,
              const std::vector<PosedImage>& queries, const PinholeCamera& q_camera, const CliArgs& args,
              const Vocabulary& voc, const OrbExtractor& extractor) {
  const double max_angle = args.get_double("max-angle"), max_dist = args.get_double("max-dist");
  const int levels_up = args.get_int("levels-up");
  auto bow_of = [&](const std::string& path, const PinholeCamera& cam) {
    const OrbFeatures f = extractor.extract(load_gray({path, 0, 0}), &cam);
    BowVector bow;
    FeatureVector fv;
    voc.transform(f.descriptors, bow, fv, levels_up);
    return bow;
  };
  KeyFrameDatabase db;
  for (std::size_t k = 0; k < keyframes.size(); ++k)
    db.add(KeyFrameId{1, std::uint32_t(k)}, bow_of(keyframes[k].path, kf_camera));
  auto neighbours = [&](KeyFrameId id) {  // stand-in covisibility: adjacent keyframes
    std::vector<KeyFrameId> out;
    if (id.seq > 0) out.push_back({1, id.seq - 1});
    if (id.seq + 1 < keyframes.size()) out.push_back({1, id.seq + 1});
    return out;
  };
  auto is_true = [&](const SE3& Tq, std::uint32_t kf) {
    const SE3& Tk = keyframes[kf].T_world_cam;
    return view_angle_deg(Tq, Tk) < max_angle && (Tq.translation() - Tk.translation()).norm() < max_dist;
  };
  Outcome plain, grouped;
  struct Top {
    double score;
    bool ok, has_true;
  };
  std::vector<Top> tops;
  for (const PosedImage& q : queries) {
    bool has_true = false;
    for (std::uint32_t k = 0; k < keyframes.size(); ++k) has_true |= is_true(q.T_world_cam, k);
    const BowVector bow = bow_of(q.path, q_camera);
    const auto ranked = db.rank(bow, 1);
    const auto groups = db.query(bow, {}, nullptr, neighbours);
    for (auto [o, top] :
         {std::pair<Outcome*, const std::vector<KeyFrameDatabase::Candidate>*>{&plain, &ranked}, {&grouped, &groups}}) {
      ++o->queries;
      o->with_true_match += has_true;
      if (top->empty()) continue;
      ++o->answered;
      const bool ok = is_true(q.T_world_cam, top->front().id.seq);
      o->correct_top1 += ok;
      o->correct_top1_with_match += ok && has_true;
      if (o == &plain) tops.push_back({top->front().score, ok, has_true});
    }
  }
  print_outcome("top score (rank)", plain);
  print_outcome("covisibility groups (query)", grouped);
  // Accepting the top candidate only above a score threshold trades recall for precision.
  std::printf("  threshold on the top score:");
  for (double th : {0.0, 0.02, 0.03, 0.04, 0.05, 0.06, 0.08, 0.10}) {
    int accepted = 0, correct = 0, with_true = 0;
    for (const Top& t : tops) {
      with_true += t.has_true;
      if (t.score < th) continue;
      ++accepted;
      correct += t.ok;
    }
    std::printf("  >=%.2f: P %.2f R %.2f", th, accepted ? double(correct) / accepted : 1.0,
                with_true ? double(correct) / with_true : 0.0);
  }
  std::printf("\n");
}

int real_sequence(const CliArgs& args, const Vocabulary& voc, const OrbExtractor& extractor) {
  const int db_every = args.get_int("db-every"), q_every = args.get_int("query-every");
  if (args.has("query-tum")) {
    // Two datasets in one world frame (e.g. two robots of a cslam-synth scene).
    const std::string db_root = args.get("tum"), q_root = args.get("query-tum");
    const TumDataset db_ds = open_tum_dataset(db_root), q_ds = open_tum_dataset(q_root);
    const auto kfs = posed_frames(db_ds, groundtruth_of(db_ds, db_root), 0, int(db_ds.rgb.size()), db_every);
    const auto qs = posed_frames(q_ds, groundtruth_of(q_ds, q_root), 0, int(q_ds.rgb.size()), q_every);
    std::printf(
        "cross-dataset: %zu keyframes of %s (every %d-th frame), %zu queries of %s (every %d-th); true match = "
        "angle < %.0f deg and distance < %.2f m\n",
        kfs.size(), db_root.c_str(), db_every, qs.size(), q_root.c_str(), q_every, args.get_double("max-angle"),
        args.get_double("max-dist"));
    evaluate(kfs, camera_of(db_root), qs, camera_of(q_root), args, voc, extractor);
    return 0;
  }
  const std::string root = args.get("tum");
  const TumDataset ds = open_tum_dataset(root);
  const Trajectory gt = groundtruth_of(ds, root);
  const int n = int(ds.rgb.size()), half = n / 2;
  const auto kfs = posed_frames(ds, gt, 0, half, db_every);
  const auto qs = posed_frames(ds, gt, half, n, q_every);
  std::printf(
      "real sequence %s: %zu keyframes (every %d-th frame of the first %d), %zu queries (every %d-th frame of the "
      "second half); true match = angle < %.0f deg and distance < %.2f m\n",
      root.c_str(), kfs.size(), db_every, half, qs.size(), q_every, args.get_double("max-angle"),
      args.get_double("max-dist"));
  const PinholeCamera cam = camera_of(root);
  evaluate(kfs, cam, qs, cam, args, voc, extractor);
  return 0;
}

int synthetic_crossing(const Vocabulary& voc, const OrbExtractor& extractor, int levels_up) {
  ProceduralImageConfig sc;
  sc.width = 2400;
  sc.height = 1800;
  sc.shapes = 1500;
  sc.lines = 300;
  sc.texts = 120;
  const cv::Mat scene = procedural_image(424242, sc);
  auto bow_of = [&](const cv::Mat& img) {
    const OrbFeatures f = extractor.extract(img);
    BowVector bow;
    FeatureVector fv;
    voc.transform(f.descriptors, bow, fv, levels_up);
    return bow;
  };
  // Robot A (client 1) drives along y = 900, robot B (client 2) along x = 1200, rotated and closer.
  KeyFrameDatabase db_a;
  std::vector<double> a_x;
  for (int x = 300; x <= 2100; x += 300) {
    db_a.add(KeyFrameId{1, std::uint32_t(a_x.size())}, bow_of(render_view(scene, x, 900, 0, 1.0)));
    a_x.push_back(x);
  }
  int overlapping = 0, first = 0;
  bool crossing_ok = false;
  for (int y = 300; y <= 1500; y += 100) {
    const auto top = db_a.rank(bow_of(render_view(scene, 1200, y, 25, 1.15)), 1);
    const bool overlaps = std::abs(y - 900) <= 150;  // B's view overlaps A's keyframe at x=1200 most
    if (!overlaps) continue;
    ++overlapping;
    const bool ok = !top.empty() && a_x[top.front().id.seq] == 1200;
    first += ok;
    if (y == 900) crossing_ok = !top.empty() && a_x[top.front().id.seq] == 1200;
  }
  std::printf(
      "synthetic crossing: robot B's crossing frame -> robot A's crossing keyframe ranks first: %s; "
      "B frames within 150 px of the crossing with A's crossing keyframe first: %d/%d\n",
      crossing_ok ? "yes" : "NO", first, overlapping);
  return crossing_ok ? 0 : 1;
}

int run(int argc, char** argv) {
  CliArgs args("cslam-bench-place", "Place-recognition recall/precision of the vocabulary and keyframe database.");
  args.option("tum", "TUM dataset folder with groundtruth.txt", std::string(CSLAM_SHARED_DATA_DIR) + "/tum_fr1_rpy")
      .option("query-tum", "second dataset in the same world frame: keyframes from --tum, queries from this one", "")
      .option("vocabulary", "vocabulary file ('default' = the committed one)", "default")
      .option("db-every", "database keyframe every n-th frame of the first half", "10")
      .option("query-every", "query every n-th frame of the second half", "1")
      .option("max-angle", "viewing-direction angle for a true match (deg)", "15")
      .option("max-dist", "position distance for a true match (m)", "0.3")
      .option("levels-up", "direct-index level counted from the leaves", "4")
      .flag("skip-synthetic", "only the real sequence");
  if (!args.parse(argc, argv)) return 0;
  std::string path = args.get("vocabulary");
  if (path == "default") path = default_vocabulary_path();
  const Vocabulary voc = Vocabulary::load(path);
  std::printf("vocabulary %s: k=%d L=%d, %zu words\n", path.c_str(), voc.branching(), voc.depth(), voc.num_words());
  const OrbExtractor extractor;
  real_sequence(args, voc, extractor);
  if (args.flag_set("skip-synthetic")) return 0;
  return synthetic_crossing(voc, extractor, args.get_int("levels-up"));
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-bench-place", argc, argv, run); }
