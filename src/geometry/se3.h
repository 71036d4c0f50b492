#pragma once
// Rigid (SE3) and similarity (Sim3) transforms. Naming: T_a_b maps points in frame b to frame a,
// so T_world_cam * p_cam = p_world, and T_a_b * T_b_c = T_a_c.
#include <Eigen/Core>
#include <Eigen/Geometry>

namespace cslam {

// Cross-product matrix: skew(v) * w == v.cross(w).
inline Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d m;
  m << 0, -v.z(), v.y(), v.z(), 0, -v.x(), -v.y(), v.x(), 0;
  return m;
}

class SE3 {
 public:
  SE3() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()) {}
  SE3(const Eigen::Quaterniond& q, const Eigen::Vector3d& t) : q_(q.normalized()), t_(t) {}
  SE3(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) : q_(Eigen::Quaterniond(R).normalized()), t_(t) {}
  static SE3 identity() { return SE3(); }
  static SE3 from_matrix(const Eigen::Matrix4d& m) {
    return SE3(Eigen::Matrix3d(m.topLeftCorner<3, 3>()), Eigen::Vector3d(m.topRightCorner<3, 1>()));
  }

  const Eigen::Quaterniond& rotation() const { return q_; }
  Eigen::Matrix3d R() const { return q_.toRotationMatrix(); }
  const Eigen::Vector3d& translation() const { return t_; }
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = R();
    m.topRightCorner<3, 1>() = t_;
    return m;
  }

  SE3 inverse() const {
    Eigen::Quaterniond qi = q_.conjugate();
    return SE3(qi, -(qi * t_));
  }
  SE3 operator*(const SE3& o) const { return SE3(q_ * o.q_, q_ * o.t_ + t_); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return q_ * p + t_; }

  // Exponential map of a twist (rho, phi): rotation by angle-axis phi, translation rho
  // (first-order "left increment" convention: T = [exp(phi) | rho] used for small updates).
  static SE3 exp_small(const Eigen::Matrix<double, 6, 1>& xi) {
    Eigen::Vector3d phi = xi.tail<3>();
    double angle = phi.norm();
    Eigen::Quaterniond q =
        angle < 1e-12 ? Eigen::Quaterniond::Identity() : Eigen::Quaterniond(Eigen::AngleAxisd(angle, phi / angle));
    return SE3(q, xi.head<3>());
  }

  // The motion `factor` times as long at the same twist, to first order in the translation:
  // rotation angle and translation scaled by `factor` (factor 1 returns *this exactly).
  SE3 scaled(double factor) const {
    if (factor == 1.0) return *this;
    const Eigen::AngleAxisd aa(q_);
    return SE3(Eigen::Quaterniond(Eigen::AngleAxisd(aa.angle() * factor, aa.axis())), t_ * factor);
  }

  double rotation_angle() const { return 2.0 * std::atan2(q_.vec().norm(), std::abs(q_.w())); }
  bool is_finite() const { return q_.coeffs().allFinite() && t_.allFinite(); }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
};

// Similarity transform p' = s R p + t.
class Sim3 {
 public:
  Sim3() : q_(Eigen::Quaterniond::Identity()), t_(Eigen::Vector3d::Zero()), s_(1.0) {}
  Sim3(const Eigen::Quaterniond& q, const Eigen::Vector3d& t, double s) : q_(q.normalized()), t_(t), s_(s) {}
  explicit Sim3(const SE3& T) : q_(T.rotation()), t_(T.translation()), s_(1.0) {}

  const Eigen::Quaterniond& rotation() const { return q_; }
  Eigen::Matrix3d R() const { return q_.toRotationMatrix(); }
  const Eigen::Vector3d& translation() const { return t_; }
  double scale() const { return s_; }

  Sim3 inverse() const {
    Eigen::Quaterniond qi = q_.conjugate();
    double si = 1.0 / s_;
    return Sim3(qi, -si * (qi * t_), si);
  }
  Sim3 operator*(const Sim3& o) const { return Sim3(q_ * o.q_, s_ * (q_ * o.t_) + t_, s_ * o.s_); }
  Eigen::Vector3d operator*(const Eigen::Vector3d& p) const { return s_ * (q_ * p) + t_; }

  // The rigid part with the translation divided by the scale is NOT what callers usually want;
  // to_se3() keeps rotation and translation as they are (valid when s is close to 1).
  SE3 to_se3() const { return SE3(q_, t_); }
  Eigen::Matrix4d matrix() const {
    Eigen::Matrix4d m = Eigen::Matrix4d::Identity();
    m.topLeftCorner<3, 3>() = s_ * R();
    m.topRightCorner<3, 1>() = t_;
    return m;
  }
  bool is_finite() const { return q_.coeffs().allFinite() && t_.allFinite() && std::isfinite(s_); }

 private:
  Eigen::Quaterniond q_;
  Eigen::Vector3d t_;
  double s_;
};

// Pose of a camera under a similarity correction of its world: if S_new_old maps the old world
// into the new one, a camera pose T_old_cam becomes T_new_cam with the same rotation change and
// its centre mapped by S (the camera's own metric scale is kept).
inline SE3 apply_sim3_to_pose(const Sim3& S_new_old, const SE3& T_old_cam) {
  return SE3(S_new_old.rotation() * T_old_cam.rotation(), S_new_old * T_old_cam.translation());
}

}  // namespace cslam
