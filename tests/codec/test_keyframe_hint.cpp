// Which full frames a byte budget is for (codec/keyframe_hint.h): the acks' keyframe hints, depth
// requests, stale hints from frames sent before a full frame that met one, and a server that sends
// none. The Python client's LeanStream makes the same choices (tests/python/test_python_codecs.py,
// KeyframeHintMatchesCpp, runs the same script).
#include <gtest/gtest.h>

#include "codec/keyframe_hint.h"

namespace cslam {
namespace {

TEST(KeyframeHint, WithoutAHintEveryFullFrameMaySpend) {
  KeyframeHint h;
  EXPECT_TRUE(h.expects_keyframe(1, true));
  h.on_full_frame(1, true);
  h.on_ack(1, 0);  // a server without hints (or tracking not under way) says 0
  h.on_ack(2, 0);
  EXPECT_TRUE(h.expects_keyframe(6, false));
  h.on_full_frame(6, false);
  EXPECT_TRUE(h.expects_keyframe(11, false));
}

TEST(KeyframeHint, AHintNamesTheFirstFullFrameAtOrAfterItsFrame) {
  KeyframeHint h;
  h.on_full_frame(1, true);
  h.on_ack(1, 10);  // keyframe at 1: the next falls due at 11
  h.on_ack(2, 9);
  h.on_ack(5, 6);
  EXPECT_FALSE(h.expects_keyframe(6, false));
  h.on_full_frame(6, false);  // not expected: leaves the hint in place
  h.on_ack(6, 5);
  h.on_ack(9, 2);
  EXPECT_FALSE(h.expects_keyframe(10, false));
  EXPECT_TRUE(h.expects_keyframe(11, false));
  EXPECT_TRUE(h.expects_keyframe(12, false));  // due at 11, which was light: the next full frame
  h.on_full_frame(12, false);
  EXPECT_FALSE(h.expects_keyframe(16, false));  // used up until a fresh hint
}

TEST(KeyframeHint, HintsFromFramesSentBeforeTheFullFrameThatMetOneAreStale) {
  KeyframeHint h;
  h.on_full_frame(1, true);
  h.on_ack(1, 10);
  h.on_full_frame(11, false);  // expected: sent before the acks of 10 and 11 came back
  h.on_ack(10, 1);             // still names 11
  EXPECT_FALSE(h.expects_keyframe(16, false));
  h.on_ack(11, 10);  // 11 became the keyframe: the next is due at 21
  EXPECT_FALSE(h.expects_keyframe(16, false));
  EXPECT_TRUE(h.expects_keyframe(21, false));
}

TEST(KeyframeHint, ADepthRequestAlwaysSpendsAndUsesTheHintUp) {
  KeyframeHint h;
  h.on_full_frame(1, true);
  h.on_ack(1, 10);
  h.on_ack(3, 0);  // a keyframe waits for depth on light frame 3 (no hint; the request says it)
  EXPECT_FALSE(h.expects_keyframe(6, false));
  EXPECT_TRUE(h.expects_keyframe(4, true));
  h.on_full_frame(4, true);
  h.on_ack(3, 0);  // stale
  EXPECT_FALSE(h.expects_keyframe(9, false));
  h.on_ack(4, 10);
  EXPECT_TRUE(h.expects_keyframe(14, false));
}

TEST(KeyframeHint, AnAckWithoutAHintLeavesTheLatestOneStanding) {
  KeyframeHint h;
  h.on_full_frame(1, true);
  h.on_ack(1, 10);
  h.on_ack(5, 0);  // a skipped or lost frame says nothing about keyframes
  EXPECT_FALSE(h.expects_keyframe(6, false));
  EXPECT_TRUE(h.expects_keyframe(11, false));
  h.on_full_frame(11, false);
  h.on_ack(12, 0);
  EXPECT_FALSE(h.expects_keyframe(16, false));  // used up, and no fresh hint
  EXPECT_FALSE(h.expects_keyframe(100, false));
  h.on_ack(20, 3);
  EXPECT_TRUE(h.expects_keyframe(23, false));
}

}  // namespace
}  // namespace cslam
