#pragma once
// Rolling-shutter compensation of a frame's keypoints.
//
// A rolling-shutter camera (the Kinect v1 and Asus Xtion of the TUM sequences, most consumer
// RGB-D cameras) exposes its rows one after another: row v of an image is captured
// (v - H/2) / H * readout_time after the middle row. While the camera turns, the image is sheared:
// at fr1/rpy's median 72 deg/s and a 20 ms readout, the top and bottom rows are seen from
// directions 1.4 deg apart, about 6 px at the image edges, against a keypoint noise of 1 px.
// Tracking and bundle adjustment assume one pose per frame, so every fast turn bends the map.
//
// With the camera's motion over half the readout (the tracker's constant-velocity prediction,
// T_lastrow_cam: the camera at the last row's instant, seen from the camera at the middle row's),
// each keypoint's 3D point (depth) or ray (no depth) is moved, to first order in that motion, from
// the camera at its row's instant into the camera at the middle row's instant, and its undistorted
// position, depth and virtual right coordinate are recomputed there. The frame then stands for a
// global-shutter image taken at the middle row's instant, which is what every later stage assumes.
#include <vector>

#include <Eigen/Core>

#include "slam/features/orb_extractor.h"
#include "geometry/camera.h"
#include "geometry/se3.h"

namespace cslam {

// Moves the undistorted keypoints (and the depth and u_right of those with depth > 0) of one
// frame from their rows' instants to the middle row's instant. `features.keypoints[i].pt.y` (the
// distorted row) gives each keypoint's instant. Points that would land behind the camera are left
// as they are. Returns the number of keypoints moved.
int compensate_rolling_shutter(const PinholeCamera& camera, double bf, const SE3& T_lastrow_cam, OrbFeatures& features,
                               std::vector<float>& depth, std::vector<float>& u_right);

}  // namespace cslam
