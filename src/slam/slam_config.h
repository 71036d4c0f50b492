#pragma once
// Configuration of one client's SLAM pipeline: plain structs with defaults.
#include "slam/features/orb_extractor.h"
#include "slam/loop/loop_closer.h"
#include "slam/map/frame_data.h"
#include "slam/mapping/local_mapper.h"
#include "slam/tracking/tracker.h"

namespace cslam {

struct SlamConfig {
  OrbConfig orb;
  RgbdParams rgbd;
  TrackerConfig tracker;
  LocalMapperConfig mapper;
  LoopClosingConfig loop;
  int bow_direct_level = 2;       // vocabulary level of the direct index used by BoW matching (root = 0)
  double max_lost_seconds = 3.0;  // lost longer than this (and relocalisation failing): start a new map
  bool threaded = true;           // local mapping in its own thread
  // At the end of a session, one global BA over each map (ClientSlam::final_global_ba): local BA
  // only ever refines a window of keyframes; 0: off.
  int final_global_ba_iterations = 10;
};

}  // namespace cslam
