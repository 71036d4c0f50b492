// FullFrameClock: a lean stream's full frames, periodic from the last full one and on request.
#include <string>

#include <gtest/gtest.h>

#include "frame/full_frame_clock.h"

namespace cslam {
namespace {

// 'F' for a full frame, '.' for a light one; `requests` marks the frames that are asked for.
std::string schedule(const std::string& requests, int depth_every) {
  FullFrameClock clock;
  std::string out;
  for (char r : requests) out += clock.next(r == 'r', depth_every) ? 'F' : '.';
  return out;
}

TEST(FullFrameClock, EveryKthFrameWithoutRequests) {
  EXPECT_EQ(schedule("r..............", 5), "F....F....F....");
  EXPECT_EQ(schedule("r....", 1), "FFFFF");
}

TEST(FullFrameClock, ARequestRestartsTheCount) {
  // Asked at frame 2 and 8: the periodic frames follow the last full one, not a fixed grid.
  EXPECT_EQ(schedule("r.r.....r......", 5), "F.F....FF....F.");
  // A request on a frame that is due anyway is one full frame.
  EXPECT_EQ(schedule("r....r.........", 5), "F....F....F....");
}

TEST(FullFrameClock, TheIntervalMayChangeBetweenFrames) {
  FullFrameClock clock;
  std::string out;
  for (int n = 0; n < 12; ++n) out += clock.next(n == 0, n < 6 ? 3 : 5) ? 'F' : '.';
  EXPECT_EQ(out, "F..F....F...");  // 3 until frame 5, then 5
}

}  // namespace
}  // namespace cslam
