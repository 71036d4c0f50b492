#include "geometry/alignment.h"

#include <cmath>

#include <Eigen/SVD>

namespace cslam {

UmeyamaResult umeyama(const Eigen::Vector3d* src, const Eigen::Vector3d* dst, int n, bool with_scale) {
  UmeyamaResult r;
  if (n < 3) return r;
  Eigen::Vector3d mu_s = Eigen::Vector3d::Zero(), mu_d = Eigen::Vector3d::Zero();
  for (int i = 0; i < n; ++i) {
    mu_s += src[i];
    mu_d += dst[i];
  }
  mu_s /= double(n);
  mu_d /= double(n);
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  double var_s = 0;
  for (int i = 0; i < n; ++i) {
    const Eigen::Vector3d a = src[i] - mu_s, b = dst[i] - mu_d;
    cov += b * a.transpose();
    var_s += a.squaredNorm();
  }
  cov /= double(n);
  var_s /= double(n);
  if (var_s < 1e-12) return r;
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(cov, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
  if (svd.matrixU().determinant() * svd.matrixV().determinant() < 0) S(2, 2) = -1;
  const Eigen::Matrix3d R = svd.matrixU() * S * svd.matrixV().transpose();
  const double s = with_scale ? (svd.singularValues().asDiagonal() * S).trace() / var_s : 1.0;
  const Eigen::Vector3d t = mu_d - s * R * mu_s;
  r.ok = std::isfinite(s) && s > 0 && R.allFinite() && t.allFinite();
  r.T_dst_src = Sim3(Eigen::Quaterniond(R), t, s);
  double sq = 0;
  for (int i = 0; i < n; ++i) sq += (r.T_dst_src * src[i] - dst[i]).squaredNorm();
  r.rmse = std::sqrt(sq / double(n));
  return r;
}

UmeyamaResult umeyama(const std::vector<Eigen::Vector3d>& src, const std::vector<Eigen::Vector3d>& dst,
                      bool with_scale) {
  if (src.size() != dst.size()) return {};
  return umeyama(src.data(), dst.data(), int(src.size()), with_scale);
}

}  // namespace cslam
