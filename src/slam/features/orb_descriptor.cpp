#include "slam/features/orb_descriptor.h"

#include <smmintrin.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>

#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include "slam/features/orb_blur.h"

namespace cslam {

namespace {

using Bytes32 = std::array<std::uint8_t, 32>;

constexpr int kPatchSize = 31;
constexpr int kBorder = 19;  // cv::ORB's: its edge threshold, as OrbConfig's default
// Probe tiles: 48 x 48 pixels, the keypoint at the centre; steps placed at -17..17 pixels from it
// cover every pattern coordinate (|x|, |y| <= 15 for a 31-pixel patch) with the blur's reach.
constexpr int kTile = 48, kCentre = 24, kReach = 17, kSteps = 2 * kReach + 1;

cv::Ptr<cv::ORB> opencv_orb() {
  return cv::ORB::create(500, 1.2f, 1, kBorder, 0, 2, cv::ORB::FAST_SCORE, kPatchSize, 20);
}

bool bit_of(const Bytes32& d, int i) { return (d[std::size_t(i >> 3)] >> (i & 7)) & 1u; }

// cv::ORB's descriptors of keypoints (angle 0) at the centre of each tile, the tiles side by side;
// empty if OpenCV dropped any keypoint.
std::vector<Bytes32> describe_tiles(const cv::Ptr<cv::ORB>& orb, const std::vector<cv::Mat>& tiles) {
  cv::Mat strip;
  cv::hconcat(tiles, strip);
  std::vector<cv::KeyPoint> kps;
  for (int t = 0; t < int(tiles.size()); ++t)
    kps.emplace_back(float(t * kTile + kCentre), float(kCentre), float(kPatchSize), 0.f, 0.f, 0, t);
  cv::Mat desc;
  orb->compute(strip, kps, desc);
  if (kps.size() != tiles.size() || desc.rows != int(tiles.size()) || desc.cols != 32) return {};
  std::vector<Bytes32> out(tiles.size());
  for (int r = 0; r < desc.rows; ++r) std::memcpy(out[std::size_t(kps[r].class_id)].data(), desc.ptr(r), 32);
  return out;
}

// One tile per step position k in [-kReach, kReach]: 255 where on(x - centre, y - centre, k), else 0.
template <class On>
std::vector<Bytes32> describe_steps(const cv::Ptr<cv::ORB>& orb, const On& on) {
  std::vector<cv::Mat> tiles;
  for (int k = -kReach; k <= kReach; ++k) {
    cv::Mat tile(kTile, kTile, CV_8UC1);
    for (int y = 0; y < kTile; ++y)
      for (int x = 0; x < kTile; ++x) tile.at<std::uint8_t>(y, x) = on(x - kCentre, y - kCentre, k) ? 255 : 0;
    tiles.push_back(tile);
  }
  return describe_tiles(orb, tiles);
}

// The step positions k (as indices 0..kSteps-1) at which bit i is set; false unless they form one
// run, whose first and last index go to lo and hi (lo > hi: none).
bool bit_run(const std::vector<Bytes32>& d, int i, int& lo, int& hi) {
  lo = kSteps, hi = -1;
  for (int s = 0; s < kSteps; ++s)
    if (bit_of(d[std::size_t(s)], i)) {
      if (hi >= 0 && hi != s - 1) return false;
      lo = std::min(lo, s);
      hi = s;
    }
  return true;
}

// The probe. The blur (7 taps per axis, all weights positive) turns a step at offset k along one
// axis into values that are 0 up to k-4, rise strictly from k-3 to k+2 and are 255 from k+3 on.
// With 255 at offset >= k ("rising"), "first point darker than the second" holds for a pair whose
// coordinates on that axis are c1 < c2 exactly when k lies in [c1-2, c2+3]; with 255 below k
// ("falling"), for c1 > c2 when k lies in [c2-2, c1+3]; for c1 == c2 never. So the first and last
// k of each run give both coordinates, except on an axis where they are equal. That coordinate c
// is found with the other axis known (o1 != o2): 255 where the equal axis is >= k and the other
// axis is on the second point's side of a line the first point lies 4 pixels beyond (blurred: 0 at
// the first point, > 0 at the second exactly where the equal axis's own blur is > 0, i.e. k <= c+3).
std::unique_ptr<OrbPattern> probe_pattern() {
  const cv::Ptr<cv::ORB> orb = opencv_orb();
  int coord[2][256][2];  // [axis][pair][point]
  bool equal[2][256] = {};
  for (int axis = 0; axis < 2; ++axis) {
    auto along = [axis](int x, int y) { return axis == 0 ? x : y; };
    const auto rising = describe_steps(orb, [&](int x, int y, int k) { return along(x, y) >= k; });
    const auto falling = describe_steps(orb, [&](int x, int y, int k) { return along(x, y) < k; });
    if (rising.empty() || falling.empty()) return nullptr;
    for (int i = 0; i < 256; ++i) {
      int rlo, rhi, flo, fhi;
      if (!bit_run(rising, i, rlo, rhi) || !bit_run(falling, i, flo, fhi)) return nullptr;
      const bool r = rlo <= rhi, f = flo <= fhi;
      if (r && f) return nullptr;
      if (r) {
        coord[axis][i][0] = rlo - kReach + 2, coord[axis][i][1] = rhi - kReach - 3;
      } else if (f) {
        coord[axis][i][1] = flo - kReach + 2, coord[axis][i][0] = fhi - kReach - 3;
      } else {
        equal[axis][i] = true;
      }
      if ((r || f) && coord[axis][i][0] == coord[axis][i][1]) return nullptr;
    }
  }
  for (int axis = 0; axis < 2; ++axis) {
    const int other = 1 - axis;
    for (int i = 0; i < 256; ++i) {
      if (!equal[axis][i]) continue;
      if (equal[other][i]) return nullptr;  // two equal points
      const int o1 = coord[other][i][0], o2 = coord[other][i][1];
      // 255 on the second point's side: beyond o1 + 4 (o2 > o1) or before o1 - 3 (o2 < o1).
      const auto d = describe_steps(orb, [&](int x, int y, int k) {
        const int a = axis == 0 ? x : y, o = axis == 0 ? y : x;
        return a >= k && (o2 > o1 ? o >= o1 + 4 : o < o1 - 3);
      });
      int lo, hi;
      if (d.empty() || !bit_run(d, i, lo, hi) || lo != 0 || hi < 0) return nullptr;
      coord[axis][i][0] = coord[axis][i][1] = hi - kReach - 3;
    }
  }
  auto pattern = std::make_unique<OrbPattern>();
  for (int i = 0; i < 256; ++i)
    for (int p = 0; p < 2; ++p) {
      const int x = coord[0][i][p], y = coord[1][i][p];
      if (std::abs(x) > kPatchSize / 2 || std::abs(y) > kPatchSize / 2) return nullptr;
      pattern->x[std::size_t(2 * i + p)] = float(x);
      pattern->y[std::size_t(2 * i + p)] = float(y);
    }
  return pattern;
}

// The pattern against cv::ORB::compute: a textured image and a nearly flat one (equal values are
// common there: "darker" must be strict), keypoints everywhere a level's keypoints may be, at
// random angles and the right angles.
bool matches_opencv(const OrbPattern& pattern) {
  const cv::Ptr<cv::ORB> orb = opencv_orb();
  cv::RNG rng(20261206);
  for (int image = 0; image < 2; ++image) {
    cv::Mat img(150, 210, CV_8UC1);
    if (image == 0)
      rng.fill(img, cv::RNG::UNIFORM, 0, 256);
    else
      rng.fill(img, cv::RNG::UNIFORM, 120, 124);
    std::vector<cv::KeyPoint> kps;
    for (int k = 0; k < 400; ++k) {
      const float angle = k < 8 ? 45.f * float(k) : rng.uniform(0.f, 360.f);
      kps.emplace_back(float(rng.uniform(kBorder, img.cols - kBorder)), float(rng.uniform(kBorder, img.rows - kBorder)),
                       float(kPatchSize), angle, 0.f, 0, k);
    }
    std::vector<cv::KeyPoint> theirs = kps;
    cv::Mat desc;
    orb->compute(img, theirs, desc);
    if (theirs.size() != kps.size() || desc.rows != int(kps.size())) return false;
    cv::Mat blurred;
    orb_blur(img, blurred);
    std::vector<Descriptor> ours;
    compute_orb_descriptors(blurred, kps, pattern, ours);
    for (int r = 0; r < desc.rows; ++r)
      if (std::memcmp(desc.ptr(r), ours[std::size_t(theirs[r].class_id)].data(), 32) != 0) return false;
  }
  return true;
}

}  // namespace

std::unique_ptr<OrbPattern> probe_opencv_orb_pattern() {
  try {
    std::unique_ptr<OrbPattern> pattern = probe_pattern();
    if (pattern && matches_opencv(*pattern)) return pattern;
  } catch (const cv::Exception&) {
  }
  return nullptr;
}

const OrbPattern* opencv_orb_pattern() {
  static const std::unique_ptr<OrbPattern> pattern = probe_opencv_orb_pattern();  // immutable once made
  return pattern.get();
}

void compute_orb_descriptors(const cv::Mat& blurred, const std::vector<cv::KeyPoint>& keypoints,
                             const OrbPattern& pattern, std::vector<Descriptor>& out) {
  const int step = int(blurred.step[0]);
  alignas(16) std::int32_t offset[512];
  const __m128i vstep = _mm_set1_epi32(step);
  for (const cv::KeyPoint& kp : keypoints) {
    // cv::ORB's arithmetic, operation for operation (this file is built without FMA contraction).
    const float angle = kp.angle * float(CV_PI / 180.f);
    const __m128 a = _mm_set1_ps(std::cos(angle)), b = _mm_set1_ps(std::sin(angle));
    const std::uint8_t* centre = blurred.ptr<std::uint8_t>(cvRound(kp.pt.y)) + cvRound(kp.pt.x);
    for (int k = 0; k < 512; k += 4) {
      const __m128 px = _mm_loadu_ps(pattern.x.data() + k), py = _mm_loadu_ps(pattern.y.data() + k);
      // cvtps rounds to nearest, ties to even, as cvRound.
      const __m128i ix = _mm_cvtps_epi32(_mm_sub_ps(_mm_mul_ps(px, a), _mm_mul_ps(py, b)));
      const __m128i iy = _mm_cvtps_epi32(_mm_add_ps(_mm_mul_ps(px, b), _mm_mul_ps(py, a)));
      _mm_store_si128(reinterpret_cast<__m128i*>(offset + k), _mm_add_epi32(_mm_mullo_epi32(iy, vstep), ix));
    }
    Descriptor d;
    auto* bytes = reinterpret_cast<std::uint8_t*>(d.data());
    for (int j = 0; j < 32; ++j) {
      unsigned v = 0;
      for (int bit = 0; bit < 8; ++bit) {
        const int i = 16 * j + 2 * bit;
        v |= unsigned(centre[offset[i]] < centre[offset[i + 1]]) << bit;
      }
      bytes[j] = std::uint8_t(v);
    }
    out.push_back(d);
  }
}

}  // namespace cslam
