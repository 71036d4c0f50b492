// cslam-bench-features: speed of ORB extraction, BoW transform, vocabulary loading, keyframe
// database queries and matching on the real sequence (one thread). Prints median and min-max.
#include <cstdio>
#include <ctime>
#include <iostream>

#include "slam/bow/keyframe_database.h"
#include "slam/bow/vocabulary.h"
#include "core/cli.h"
#include "core/stopwatch.h"
#include "core/stats.h"
#include "slam/features/matching.h"
#include "slam/features/orb_extractor.h"
#include "geometry/camera.h"
#include "image_sources.h"

using namespace cslam;

namespace {

void report(const char* what, const std::vector<double>& values, const char* unit = "ms") {
  const Summary s = summarize(values);
  std::printf("%-34s n=%4d  median %8.3f %s  min %8.3f  max %8.3f  mean %8.3f  p95 %8.3f\n", what, s.n, s.median, unit,
              s.min, s.max, s.mean, s.p95);
}

int run(int argc, char** argv) {
  CliArgs args("cslam-bench-features",
               "Benchmarks ORB extraction, BoW transform, vocabulary load, keyframe database "
               "queries and matching on a TUM sequence (single thread).");
  args.option("tum", "TUM dataset folder", std::string(CSLAM_SHARED_DATA_DIR) + "/tum_fr1_rpy")
      .option("every", "use every n-th frame", "1")
      .option("vocabulary", "vocabulary file ('default' = the committed one)", "default")
      .option("levels-up", "direct-index level counted from the leaves", "4")
      .option("features", "ORB keypoints per frame", "1000");
  if (!args.parse(argc, argv)) return 0;
  cv::setNumThreads(1);  // one core: no OpenCV worker threads inside the timed calls

  const auto sources = tum_images(args.get("tum"), args.get_int("every"));
  std::vector<cv::Mat> images;
  for (const auto& s : sources) images.push_back(load_gray(s));
  std::printf("%zu frames of %s (%dx%d)\n", images.size(), args.get("tum").c_str(), images[0].cols, images[0].rows);

  OrbConfig orb;
  orb.num_features = args.get_int("features");
  const OrbExtractor extractor(orb);
  const PinholeCamera camera = camera_tum_fr1();
  extractor.extract(images[0], &camera);  // warm-up
  std::vector<OrbFeatures> features;
  std::vector<double> t_extract, cpu_extract, n_kp;
  for (const cv::Mat& img : images) {
    Stopwatch sw;
    const double cpu0 = thread_cpu_ms();
    features.push_back(extractor.extract(img, &camera));
    cpu_extract.push_back(thread_cpu_ms() - cpu0);
    t_extract.push_back(sw.ms());
    n_kp.push_back(double(features.back().size()));
  }
  report("ORB extraction wall (incl. undist.)", t_extract);
  report("ORB extraction thread CPU time", cpu_extract);
  report("keypoints per frame", n_kp, "kp");

  std::string path = args.get("vocabulary");
  if (path == "default") path = default_vocabulary_path();
  std::vector<double> t_load;
  Vocabulary voc;
  for (int i = 0; i < 5; ++i) {
    Stopwatch sw;
    voc = Vocabulary::load(path);
    t_load.push_back(sw.ms());
  }
  std::printf("vocabulary %s: k=%d L=%d, %zu words\n", path.c_str(), voc.branching(), voc.depth(), voc.num_words());
  report("vocabulary load", t_load);

  const int levels_up = args.get_int("levels-up");
  std::vector<BowVector> bows(features.size());
  std::vector<FeatureVector> fvs(features.size());
  std::vector<double> t_bow, t_bow_plain, cpu_bow;
  for (std::size_t i = 0; i < features.size(); ++i) {
    Stopwatch sw;
    const double cpu0 = thread_cpu_ms();
    voc.transform(features[i].descriptors, bows[i], fvs[i], levels_up);
    cpu_bow.push_back(thread_cpu_ms() - cpu0);
    t_bow.push_back(sw.ms());
    BowVector plain;
    sw.reset();
    voc.transform(features[i].descriptors, plain);
    t_bow_plain.push_back(sw.ms());
  }
  report("BoW transform + feature vector", t_bow);
  report("  (thread CPU time)", cpu_bow);
  report("BoW transform only", t_bow_plain);

  KeyFrameDatabase db;
  for (std::size_t i = 0; i < bows.size(); ++i) db.add(KeyFrameId{0, std::uint32_t(i)}, bows[i]);
  std::vector<double> t_query;
  KeyFrameDatabase::QueryParams qp;
  for (std::size_t i = 0; i < bows.size(); ++i) {
    const KeyFrameId self{0, std::uint32_t(i)};
    auto neighbours = [&](KeyFrameId id) {
      std::vector<KeyFrameId> n;
      for (int d = -3; d <= 3; ++d)
        if (d != 0 && int(id.seq) + d >= 0 && int(id.seq) + d < int(bows.size()))
          n.push_back({0, std::uint32_t(int(id.seq) + d)});
      return n;
    };
    Stopwatch sw;
    db.query(
        bows[i], qp, [&](KeyFrameId id) { return id == self; }, neighbours);
    t_query.push_back(sw.ms());
  }
  char label[64];
  std::snprintf(label, sizeof label, "database query (%zu keyframes)", db.size());
  report(label, t_query);

  std::vector<double> t_bf, t_bowm, n_bf, n_bowm;
  MatchParams mp;
  for (std::size_t i = 1; i < features.size(); i += 5) {
    Stopwatch sw;
    auto m1 = match_brute_force(features[i - 1], features[i], mp);
    t_bf.push_back(sw.ms());
    sw.reset();
    auto m2 = match_by_bow(features[i - 1], fvs[i - 1], features[i], fvs[i], mp);
    t_bowm.push_back(sw.ms());
    n_bf.push_back(double(m1.size()));
    n_bowm.push_back(double(m2.size()));
  }
  report("brute-force matching (consecutive)", t_bf);
  report("  matches", n_bf, "m");
  report("BoW matching (consecutive)", t_bowm);
  report("  matches", n_bowm, "m");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-bench-features", argc, argv, run); }
