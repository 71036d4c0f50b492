// cslam-vocab: trains a bag-of-words vocabulary from TUM datasets, image folders and procedural
// images (train), and prints the shape and statistics of a vocabulary file (info).
#include <cstdio>
#include <iostream>
#include <mutex>

#include "slam/bow/vocabulary.h"
#include "core/cli.h"
#include "core/error.h"
#include "core/log.h"
#include "core/stopwatch.h"
#include "slam/features/orb_extractor.h"
#include "image_sources.h"

using namespace cslam;

namespace {

int cmd_train(int argc, char** argv) {
  CliArgs args("cslam-vocab train",
               "Trains a vocabulary (hierarchical k-majority, TF-IDF) from ORB features of every n-th frame.");
  args.multi_option("tum", "TUM RGB-D dataset folders (rgb.txt)")
      .multi_option("images", "folders of png/jpg images")
      .option("every", "use every n-th frame of each dataset/folder", "1")
      .option("synthetic-images", "number of procedural images added to the training set", "0")
      .option("synthetic-seed", "seed of the first procedural image", "1000")
      .option("features", "ORB keypoints per image", "1000")
      .option("branching", "branching factor k", "10")
      .option("depth", "depth L", "5")
      .option("iterations", "k-majority iterations per node", "10")
      .option("threads", "worker threads", "2")
      .option("seed", "clustering seed", "1")
      .option("out", "output vocabulary file");
  if (!args.parse(argc, argv, 2)) return 0;
  auto log = logger("vocab");

  std::vector<ImageSource> sources;
  const int every = args.get_int("every");
  for (const std::string& dir : args.get_multi("tum")) {
    auto s = tum_images(dir, every);
    log->info("{}: {} frames (every {})", dir, s.size(), every);
    sources.insert(sources.end(), s.begin(), s.end());
  }
  for (const std::string& dir : args.get_multi("images")) {
    auto s = folder_images(dir, every);
    log->info("{}: {} images (every {})", dir, s.size(), every);
    sources.insert(sources.end(), s.begin(), s.end());
  }
  const int n_synth = args.get_int("synthetic-images");
  if (n_synth > 0) {
    auto s = procedural_images(n_synth, std::uint64_t(args.get_int("synthetic-seed")));
    sources.insert(sources.end(), s.begin(), s.end());
    log->info("procedural: {} images (seeds {}..)", n_synth, args.get("synthetic-seed"));
  }
  if (sources.empty()) throw ConfigError("cslam-vocab train: no images (give --tum, --images or --synthetic-images)");

  VocabularyTrainConfig config;
  config.branching = args.get_int("branching");
  config.depth = args.get_int("depth");
  config.max_iterations = args.get_int("iterations");
  config.threads = args.get_int("threads");
  config.seed = std::uint64_t(args.get_int("seed"));
  OrbConfig orb;
  orb.num_features = args.get_int("features");
  const OrbExtractor extractor(orb);

  Stopwatch sw;
  std::vector<std::vector<Descriptor>> descriptors(sources.size());
  std::mutex progress_mutex;
  std::size_t done = 0, total_desc = 0;
  parallel_for_each(sources.size(), config.threads, [&](std::size_t i) {
    descriptors[i] = extractor.extract(load_gray(sources[i])).descriptors;
    std::lock_guard<std::mutex> lock(progress_mutex);
    ++done;
    total_desc += descriptors[i].size();
    if (done % 100 == 0 || done == sources.size())
      log->info("features: {}/{} images, {} descriptors", done, sources.size(), total_desc);
  });
  log->info("extraction took {:.1f} s", sw.ms() / 1000);

  sw.reset();
  const Vocabulary voc = Vocabulary::train(descriptors, config, [&](int level, int levels) {
    log->info("clustering: level {}/{} done ({:.1f} s)", level, levels, sw.ms() / 1000);
  });
  log->info("training took {:.1f} s: {} words, {} nodes", sw.ms() / 1000, voc.num_words(), voc.num_nodes());
  voc.save(args.get("out"));
  log->info("wrote {}", args.get("out"));
  return 0;
}

int cmd_info(int argc, char** argv) {
  CliArgs args("cslam-vocab info", "Prints the shape and statistics of a vocabulary file.");
  args.positional("FILE", "vocabulary file (default vocabulary: give 'default')");
  if (!args.parse(argc, argv, 2)) return 0;
  std::string path = args.positionals()[0];
  if (path == "default") path = default_vocabulary_path();
  Stopwatch sw;
  const Vocabulary voc = Vocabulary::load(path);
  const double load_ms = sw.ms();
  const VocabularyStats s = voc.stats();
  std::printf("file        %s\n", path.c_str());
  std::printf("load time   %.1f ms\n", load_ms);
  std::printf("branching   %d\ndepth       %d\nnodes       %zu\nwords       %zu\n", s.branching, s.depth, s.num_nodes,
              s.num_words);
  std::printf("words per depth:");
  for (std::size_t l = 0; l < s.words_per_level.size(); ++l) std::printf(" %zu:%zu", l, s.words_per_level[l]);
  std::printf("\nmean word depth %.2f\n", s.mean_word_depth);
  std::printf("idf weight  min %.3f  mean %.3f  max %.3f  (zero-weight words %zu)\n", s.min_weight, s.mean_weight,
              s.max_weight, s.zero_weight_words);
  return 0;
}

void usage() {
  std::cout << "Usage: cslam-vocab <command> [options]\n"
               "Bag-of-words vocabulary tools.\n\n"
               "Commands:\n"
               "  train   train a vocabulary from TUM datasets, image folders and procedural images\n"
               "  info    print the shape and statistics of a vocabulary file\n\n"
               "Run 'cslam-vocab <command> --help' for the options of a command.\n";
}

int run(int argc, char** argv) {
  if (argc < 2 || std::string(argv[1]) == "--help" || std::string(argv[1]) == "-h") {
    usage();
    return argc < 2 ? 2 : 0;
  }
  const std::string cmd = argv[1];
  if (cmd == "train") return cmd_train(argc, argv);
  if (cmd == "info") return cmd_info(argc, argv);
  std::cerr << "cslam-vocab: unknown command '" << cmd << "' (see --help)\n";
  return 2;
}

}  // namespace

int main(int argc, char** argv) { return run_main("cslam-vocab", argc, argv, run); }
