// Flow frames: the tracker's side (frame_flow.h).
#include <algorithm>
#include <cmath>
#include <mutex>
#include <shared_mutex>

#include "core/log.h"
#include "slam/tracking/tracker.h"

namespace cslam {

std::optional<FlowSeeds> Tracker::flow_seeds(double timestamp, int max_run) {
  const FlowConfig& fc = config_.flow;
  if (state_ != FrameFate::kTracked || !has_velocity_ || !last_ || !last_->has_pose || keyframe_deferred_)
    return std::nullopt;
  if (flow_run_ >= max_run || frames_since_reloc_ < std::uint32_t(config_.max_frames_between_keyframes))
    return std::nullopt;
  // A keyframe due at this frame by the frame count needs the full path (and its keypoints).
  if (config_.keyframe_every_frames > 0 && frames_since_keyframe_ + 1 >= std::uint32_t(config_.keyframe_every_frames))
    return std::nullopt;
  const double dt = timestamp - last_->data->timestamp;
  if (!(dt > 0) || !(velocity_dt_ > 0)) return std::nullopt;
  flow_estimate_ = -1;
  FlowSeeds seeds;
  std::shared_lock<std::shared_mutex> lock(map_->mutex);
  flow_change_index_ = map_->big_change_index();
  // As track() does: the last pose through its reference keyframe (local BA may have moved it), and
  // visual-odometry points for its close keypoints without a map point, which the flow carries too.
  update_last_frame();
  seeds.T_cam_world = motion_model_pose(timestamp);
  const FrameData& f = *last_->data;
  // Map points first, then visual-odometry points, each thinned evenly to the seed budget.
  std::vector<int> in_view[2];
  std::vector<cv::Point2f> px_in_view[2];
  int real = 0;
  for (std::size_t i = 0; i < last_->map_points.size(); ++i) {
    const auto& mp = last_->map_points[i];
    if (!mp || last_->outlier[i] || mp->bad) continue;
    const int kind = mp->observations.empty() ? 1 : 0;
    real += 1 - kind;
    const Eigen::Vector3d pc = seeds.T_cam_world * mp->position;
    if (pc.z() <= 0) continue;
    const Eigen::Vector2d uv = f.camera.project(pc);
    if (!f.in_bounds(uv.x(), uv.y())) continue;
    const Eigen::Vector2d px = f.camera.distort_pixel(uv);
    in_view[kind].push_back(int(i));
    px_in_view[kind].emplace_back(float(px.x()), float(px.y()));
  }
  int budget = fc.max_seeds;
  for (int kind = 0; kind < 2; ++kind) {
    const std::size_t n = in_view[kind].size(), take = std::min<std::size_t>(n, std::size_t(std::max(0, budget)));
    for (std::size_t k = 0; k < take; ++k) {
      const std::size_t j = k * n / take;
      seeds.index.push_back(in_view[kind][j]);
      seeds.predicted.push_back(px_in_view[kind][j]);
    }
    if (kind == 0) flow_seeded_ = int(take);
    budget -= int(take);
  }
  // The share of the last frame's map points still in view, for the survival estimate.
  flow_in_view_ = real > 0 ? double(in_view[0].size()) / real : 0.0;
  if (flow_run_ == 0) flow_survival_ = 1.0;
  if (flow_seeded_ < fc.min_inliers) return std::nullopt;
  return seeds;
}

bool Tracker::keyframe_may_be_due(const Frame& frame, int inliers) {
  // The keyframe rule (need_new_keyframe) runs on full frames, on their local-map inliers. A flow
  // frame estimates them: the last full frame's, scaled by the fraction of its points the flow
  // still holds, times a calibration (below). It goes the full way whenever the rule could fire
  // on that estimate.
  if (flow_seeded_ <= 0) return true;
  const double survival = flow_survival_ * flow_in_view_ * inliers / flow_seeded_;
  flow_estimate_ = full_inliers_ * survival;
  // The flow keeps points that descriptor matching loses (blur, viewpoint), so the estimate runs
  // high at times. Each frame the flow passed to the full path measures actual / estimated; the
  // estimate is scaled by a low quantile of the recent ratios, and with too few of them the
  // frame goes the full way (which measures one).
  if (flow_calibration_.size() < std::size_t(config_.flow.calibration_min)) return true;
  std::vector<double> sorted(flow_calibration_.begin(), flow_calibration_.end());
  std::sort(sorted.begin(), sorted.end());
  const double scale = sorted[std::size_t(config_.flow.calibration_quantile * double(sorted.size() - 1))];
  const double local = flow_estimate_ * scale, local_close = full_close_ * survival * scale;
  const std::size_t nkfs = map_->num_keyframes();
  const int ref_matches =
      reference_kf_ ? reference_kf_->tracked_map_points(nkfs <= 2 ? 2 : config_.ref_min_observations) : 0;
  const double ratio = nkfs < 2 ? 0.4 : config_.ref_ratio;
  const bool need_close = local_close < config_.close_tracked_threshold;
  const bool interval_passed =
      !last_keyframe_ || frame.data->timestamp - last_keyframe_->data->timestamp >= config_.min_keyframe_interval_s;
  return need_close || local < ref_matches * 0.25 || (interval_passed && local < ref_matches * ratio);
}

void Tracker::calibrate_flow() {
  if (flow_estimate_ > 0) {
    flow_calibration_.push_back(last_inliers_ / flow_estimate_);
    if (flow_calibration_.size() > std::size_t(config_.flow.calibration_window)) flow_calibration_.pop_front();
  }
  flow_estimate_ = -1;
}

std::optional<TrackResult> Tracker::track_flow(const FlowFrame& flow) {
  const FlowConfig& fc = config_.flow;
  if (!last_ || int(flow.previous_index.size()) < fc.min_inliers) return std::nullopt;
  Frame frame(flow.data);
  frame.T_cam_world = motion_model_pose(frame.data->timestamp);  // as flow_seeds predicted it
  frame.has_pose = true;
  int inliers = 0;
  {
    std::shared_lock<std::shared_mutex> lock(map_->mutex);
    if (map_->big_change_index() != flow_change_index_) return std::nullopt;  // the map moved: the full path
    for (std::size_t k = 0; k < flow.previous_index.size(); ++k) {
      const auto& mp = last_->map_points[std::size_t(flow.previous_index[k])];
      if (mp && !mp->bad) frame.map_points[k] = mp;
    }
    optimize_frame_pose(frame);
    // Outliers and visual-odometry points go (the next frame makes its own from this frame's
    // depth, as after a full frame); the keypoints stay.
    for (std::size_t i = 0; i < frame.map_points.size(); ++i) {
      if (!frame.map_points[i]) continue;
      if (frame.outlier[i] || frame.map_points[i]->observations.empty()) {
        frame.map_points[i].reset();
        frame.outlier[i] = 0;
      } else {
        ++inliers;
      }
    }
    if (inliers < fc.min_inliers || keyframe_may_be_due(frame, inliers)) {
      logger("tracking")
          ->debug("frame {}: flow {} inliers of {} (last full frame {}): full path", frame.data->id.seq, inliers,
                  flow.previous_index.size(), full_inliers_);
      return std::nullopt;
    }
    // The points' found / visible counts are left to full frames: they measure how often the
    // local-map search matches a point it projects into view, which map point culling reads (a
    // recent point matched in under a quarter of the frames that should see it goes). A flow frame
    // runs no such search. It follows at most FlowConfig::max_seeds of the last frame's matches and
    // projects nothing else, so counting its seeds found and the rest of the local map in view but
    // not found sampled another rate, and culled points a full frame keeps (the accuracy it cost:
    // docs/results/capacity.md, "Flow frames without match counts").
    if (KeyFrame* best = most_sharing(keyframes_sharing(frame)))
      if (KeyFramePtr ref = map_->shared(best)) reference_kf_ = std::move(ref);
    frame.reference = reference_kf_;
    if (frame.reference) frame.T_cam_ref = frame.T_cam_world * frame.reference->T_world_cam();
  }
  flow_estimate_ = -1;
  velocity_ = frame.T_cam_world * last_->T_cam_world.inverse();
  velocity_dt_ = frame.data->timestamp - last_->data->timestamp;
  ++frames_since_keyframe_;
  ++frames_since_reloc_;
  ++flow_run_;
  flow_survival_ *= flow_in_view_ * inliers / flow_seeded_;
  TrackResult result;
  result.state = state_;
  result.ok = true;
  result.inliers = inliers;
  result.T_cam_world = frame.T_cam_world;
  result.reference = frame.reference;
  result.T_cam_ref = frame.T_cam_ref;
  result.flow = true;
  result.keyframe_due_in = keyframe_due_in(frames_since_keyframe_);
  last_is_keyframe_ = false;
  if (!last_full_) last_full_ = std::move(last_);
  last_ = std::make_unique<Frame>(std::move(frame));
  return result;
}

}  // namespace cslam
