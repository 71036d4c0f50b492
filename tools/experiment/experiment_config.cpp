#include "experiment_config.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "core/error.h"
#include "eval/split.h"

namespace cslam::experiment {

namespace {

std::vector<std::string> split_commas(const std::string& text) {
  std::vector<std::string> items;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    const auto b = item.find_first_not_of(" \t"), e = item.find_last_not_of(" \t");
    items.push_back(b == std::string::npos ? std::string() : item.substr(b, e - b + 1));
  }
  return items;
}

std::string safe_name(std::string s) {
  for (char& c : s)
    if (!std::isalnum(static_cast<unsigned char>(c)) && c != '_' && c != '-') c = '_';
  return s;
}

}  // namespace

const char* to_string(RunMode mode) {
  return mode == RunMode::kOffline ? "offline" : mode == RunMode::kLive ? "live" : "network";
}

RunMode parse_mode(const std::string& text) {
  if (text == "offline") return RunMode::kOffline;
  if (text == "network") return RunMode::kNetwork;
  if (text == "live") return RunMode::kLive;
  throw ConfigError("cslam-experiment: --mode must be 'offline', 'network' or 'live', got '" + text + "'");
}

std::vector<double> parse_overlaps(const std::string& text) {
  std::vector<double> out;
  for (std::string item : split_commas(text)) {
    if (!item.empty() && item.back() == '%') item.pop_back();
    double v = 0;
    std::size_t used = 0;
    try {
      v = std::stod(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || !std::isfinite(v))
      throw ConfigError("cslam-experiment: --overlaps expects percentages like 0.5,2.5,5,10; bad item '" + item + "'");
    if (v < 0 || v >= 50)
      throw ConfigError("cslam-experiment: --overlaps are percent in [0, 50), got " + item + " (write 5 for 5 %)");
    if (std::find(out.begin(), out.end(), v) == out.end()) out.push_back(v);
  }
  if (out.empty()) throw ConfigError("cslam-experiment: --overlaps is empty");
  return out;
}

std::vector<int> parse_client_counts(const std::string& text, int max_clients) {
  std::vector<int> out;
  for (const std::string& item : split_commas(text)) {
    int v = 0;
    std::size_t used = 0;
    try {
      v = std::stoi(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || v < 1 || v > max_clients)
      throw ConfigError("cslam-experiment: --clients expects numbers 1.." + std::to_string(max_clients) +
                        " like 1,2,3; bad item '" + item + "'");
    if (std::find(out.begin(), out.end(), v) != out.end())
      throw ConfigError("cslam-experiment: --clients lists " + item + " twice");
    out.push_back(v);
  }
  if (out.empty()) throw ConfigError("cslam-experiment: --clients is empty");
  std::sort(out.begin(), out.end());
  return out;
}

std::string overlap_text(double percent) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", percent);
  return buf;
}

std::vector<RunConfig> build_matrix(const ExperimentOptions& options, const std::vector<std::string>& dataset_dirs,
                                    const std::vector<int>& frame_counts) {
  std::vector<RunConfig> out;
  const bool split = dataset_dirs.size() == 1 && options.datasets.empty() && options.synthetic_dir.empty();
  if (split) {
    const int n = frame_counts.at(0);
    for (int k : options.clients) {
      if (k == 1) {
        RunConfig c;
        c.name = "single";
        c.label = "single";
        c.clients = 1;
        c.split = true;
        c.specs.push_back({1, dataset_dirs[0], 1, n});
        out.push_back(c);
        continue;
      }
      for (double eta : options.overlaps_percent) {
        const SplitResult s = split_sequence(n, k, eta / 100.0);
        RunConfig c;
        c.name = "k" + std::to_string(k) + "_eta" + safe_name(overlap_text(eta));
        c.label = std::to_string(k) + " clients";
        c.clients = k;
        c.overlap_percent = eta;
        c.split = true;
        for (int i = 0; i < k; ++i) c.specs.push_back({i + 1, dataset_dirs[0], s.ranges[i].first, s.ranges[i].last});
        out.push_back(c);
      }
    }
    return out;
  }
  const int available = int(dataset_dirs.size());
  for (int k : options.clients) {
    if (k > available)
      throw ConfigError("cslam-experiment: --clients " + std::to_string(k) + " needs " + std::to_string(k) +
                        " datasets, only " + std::to_string(available) + " given");
    if (k == 1) {
      for (int d = 0; d < available; ++d) {
        const std::string base = std::filesystem::path(dataset_dirs[d]).filename().string();
        RunConfig c;
        c.name = "single_" + safe_name(base);
        c.label = "single (" + base + ")";
        c.clients = 1;
        c.specs.push_back({1, dataset_dirs[d], 1, frame_counts[d]});
        out.push_back(c);
      }
      continue;
    }
    RunConfig c;
    c.name = "k" + std::to_string(k);
    c.label = std::to_string(k) + " clients";
    c.clients = k;
    for (int i = 0; i < k; ++i) c.specs.push_back({i + 1, dataset_dirs[i], 1, frame_counts[i]});
    out.push_back(c);
  }
  return out;
}

}  // namespace cslam::experiment
