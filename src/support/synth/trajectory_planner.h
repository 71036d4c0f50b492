#pragma once
// Robot trajectories for the synthetic scene. All robots move in the furniture-free walkway (an
// ellipse in the middle of the room) and look outwards at walls and furniture, so surfaces are
// mostly 0.8-4 m away.
//  - Arc robots follow the walkway ellipse; each one's arc starts inside the previous robot's arc
//    (`overlap` of it is shared), and at the same place every robot looks the same way, so the
//    robots genuinely revisit each other's places.
//  - With `loop`, robot 1 drives a full circle around the room centre while looking outwards
//    (a 360-degree panorama) and returns to its start pose: a loop closure.
// Motion starts and ends at rest with smooth (cosine) acceleration ramps and respects the
// per-frame limits (default 2 cm and 1.5 degrees at 30 Hz).
#include <string>
#include <vector>

#include "io/trajectory_io.h"
#include "support/synth/scene.h"

namespace cslam::synth {

struct TrajectoryConfig {
  int robots = 3;
  int frames = 300;  // per robot
  double rate_hz = 30.0;
  double start_time = 1000000000.0;  // timestamp of every robot's first frame
  bool loop = true;                  // robot 1 drives a closed loop back to its start
  double overlap = 0.35;             // share of each arc robot's path that the next one retraces
  double speed = 0.45;               // nominal speed of arc robots, m/s (lowered to meet the limits)
  double max_step = 0.02;            // metres per frame
  double max_rotation_deg = 1.5;     // degrees per frame
  double min_height = 0.3, max_height = 1.5;
  double ramp_fraction = 0.1;  // acceleration ramp, share of the frames (at least 1 s, at most 1/4)

  // Throws ConfigError naming the first impossible value.
  void validate() const;
};

struct RobotPlan {
  std::string kind;                   // "loop" or "arc"
  double phi_start = 0, phi_end = 0;  // parameter range on the walkway ellipse / loop circle (rad)
  double radius = 0;                  // loop circle radius (loop robots)
  double base_height = 0;
  Trajectory trajectory;  // T_world_cam, timestamps start_time + i / rate_hz
};

struct TrajectoryPlan {
  std::vector<RobotPlan> robots;
};

// Plans config.robots trajectories of config.frames poses each in the scene (deterministic in the
// scene seed). Throws ConfigError if they cannot fit (e.g. a loop with too few frames).
TrajectoryPlan plan_trajectories(const Scene& scene, const TrajectoryConfig& config);

// One long trajectory visiting the robots' paths one after the other, joined by smooth
// straight transitions (inside the walkway), timestamps from config.start_time at config.rate_hz.
Trajectory make_whole_sequence(const TrajectoryPlan& plan, const TrajectoryConfig& config);

// Pose between a and b (linear position, spherical-linear rotation), alpha in [0, 1].
SE3 interpolate_pose(const SE3& a, const SE3& b, double alpha);

// Camera pose with yaw about world z (0 = looking along +x), pitch up positive, no roll.
SE3 camera_pose(const Eigen::Vector3d& position, double yaw, double pitch);

struct TrajectoryCheck {
  bool ok = true;
  std::string problem;                        // first violation, empty if ok
  double max_step = 0, max_rotation_deg = 0;  // per frame
  double max_acceleration = 0;                // m/s^2 from second differences
  double min_furniture_distance = 1e9;        // 2D distance of the camera centre to any footprint
  double min_wall_distance = 1e9;
  double min_height = 1e9, max_height = -1e9;
};

// Checks a trajectory against the room, the furniture and the per-frame limits.
TrajectoryCheck check_trajectory(const Scene& scene, const Trajectory& trajectory, const TrajectoryConfig& limits,
                                 double min_clearance = 0.25, double min_wall_distance = 0.3);

}  // namespace cslam::synth
