// Relocalisation: BoW candidates from the client's keyframe database, PnP RANSAC on the BoW
// matches, pose optimisation, and a projection search for more matches.
#include <opencv2/calib3d.hpp>

#include "slam/match/projection_search.h"
#include "slam/tracking/tracker.h"

namespace cslam {

bool Tracker::relocalize(Frame& frame) {
  frame.data = with_bow(std::move(frame.data));
  const FrameData& f = *frame.data;
  KeyFrameDatabase::QueryParams params;
  params.min_score = 0;
  const auto candidates = map_->database.query(
      f.bow, params, [](KeyFrameId) { return false; },
      [this](KeyFrameId id) {
        std::vector<KeyFrameId> out;
        if (auto kf = map_->keyframe(id))
          for (KeyFrame* n : kf->best_covisibles(10)) out.push_back(n->id);
        return out;
      });
  const cv::Matx33d K(f.camera.fx, 0, f.camera.cx, 0, f.camera.fy, f.camera.cy, 0, 0, 1);
  for (const auto& cand : candidates) {
    KeyFramePtr kf = map_->keyframe(cand.id);
    if (!kf || kf->bad) continue;
    std::vector<MapPointPtr> matches;
    if (search_by_bow(*kf, f, matches, 0.75, true) < config_.reloc_min_bow_matches) continue;
    std::vector<cv::Point3f> object;
    std::vector<cv::Point2f> image;
    std::vector<int> index;
    for (size_t i = 0; i < matches.size(); ++i) {
      if (!matches[i]) continue;
      const auto& p = matches[i]->position;
      object.emplace_back(float(p.x()), float(p.y()), float(p.z()));
      image.emplace_back(float(f.features.undistorted[i].x()), float(f.features.undistorted[i].y()));
      index.push_back(int(i));
    }
    cv::Mat rvec, tvec;
    std::vector<int> inliers;
    if (!cv::solvePnPRansac(object, image, K, cv::noArray(), rvec, tvec, false, 300, 4.0f, 0.99, inliers,
                            cv::SOLVEPNP_EPNP) ||
        int(inliers.size()) < 10)
      continue;
    cv::Mat R;
    cv::Rodrigues(rvec, R);
    Eigen::Matrix3d Re;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) Re(r, c) = R.at<double>(r, c);
    frame.T_cam_world = SE3(Re, Eigen::Vector3d(tvec.at<double>(0), tvec.at<double>(1), tvec.at<double>(2)));
    frame.has_pose = true;
    std::fill(frame.map_points.begin(), frame.map_points.end(), nullptr);
    std::fill(frame.outlier.begin(), frame.outlier.end(), 0);
    for (int k : inliers) frame.map_points[index[k]] = matches[index[k]];
    int good = optimize_frame_pose(frame);
    if (good < 10) continue;
    auto drop_outliers = [&] {
      for (size_t i = 0; i < frame.map_points.size(); ++i)
        if (frame.outlier[i]) {
          frame.map_points[i].reset();
          frame.outlier[i] = 0;
        }
    };
    drop_outliers();
    if (good < config_.reloc_min_inliers) {
      std::set<MapPoint*> already;
      for (const auto& mp : frame.map_points)
        if (mp) already.insert(mp.get());
      const int added = search_by_projection_keyframe(frame, *kf, already, 10, 100);
      if (good + added >= config_.reloc_min_inliers) {
        good = optimize_frame_pose(frame);
        drop_outliers();
      }
    }
    if (good >= config_.reloc_min_inliers) {
      reference_kf_ = kf;
      frame.reference = kf;
      return true;
    }
  }
  return false;
}

}  // namespace cslam
