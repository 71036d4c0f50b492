// SystemConfig::tracking_slots: the client workers share that many tracking slots, served in
// arrival order. With one slot, a worker that is busy with a frame holds the other clients'
// workers until it is done; without a limit they go on.
#include <chrono>
#include <condition_variable>
#include <future>
#include <mutex>
#include <set>
#include <thread>

#include <gtest/gtest.h>

#include "common/small_camera.h"
#include "system/collaborative_system.h"

using namespace cslam;

namespace {

RgbdFrame frame_of(ClientId client, std::uint64_t seq) {
  const PinholeCamera cam = test::small_camera();
  RgbdFrame f;
  f.client = client;
  f.seq = seq;
  f.timestamp = double(seq) / 30.0;
  f.bgr = test::plane_colour(cam);
  f.depth = test::plane_depth(cam, 1.0);
  return f;
}

// Client 1's first frame holds its worker (in the frame-done report) until `release` is set; then
// client 2 submits a frame. Returns whether client 2's frame was reported while client 1 was held,
// and the number of workers that were waiting for a slot meanwhile.
struct Outcome {
  bool second_done_while_held = false;
  std::size_t waiters_seen = 0;
};

Outcome run_with_slots(int slots) {
  SystemConfig sc;
  sc.run_slam = false;  // counting pipelines: the scheduling alone
  sc.tracking_slots = slots;
  std::mutex mutex;
  std::condition_variable cv;
  std::set<ClientId> done;
  std::promise<void> held, release;
  std::shared_future<void> released = release.get_future().share();
  sc.on_frame_done = [&](const FrameDone& d) {
    if (d.client == 1) {
      held.set_value();
      released.wait();
    }
    std::lock_guard<std::mutex> lock(mutex);
    done.insert(d.client);
    cv.notify_all();
  };
  CollaborativeSystem system(sc);
  system.add_client({1, "one", test::small_camera()});
  system.add_client({2, "two", test::small_camera()});
  EXPECT_TRUE(system.submit(frame_of(1, 1)));
  held.get_future().wait();
  EXPECT_TRUE(system.submit(frame_of(2, 1)));
  Outcome out;
  if (slots == 1) {
    // Until client 2's worker waits for the slot, or (wrongly) got its frame done without it.
    for (;;) {
      out.waiters_seen = system.tracking_slot_waiters();
      std::lock_guard<std::mutex> lock(mutex);
      out.second_done_while_held = done.count(2) > 0;
      if (out.waiters_seen > 0 || out.second_done_while_held) break;
    }
  } else {
    std::unique_lock<std::mutex> lock(mutex);
    out.second_done_while_held = cv.wait_for(lock, std::chrono::seconds(60), [&] { return done.count(2) > 0; });
    out.waiters_seen = system.tracking_slot_waiters();
  }
  release.set_value();
  {
    std::unique_lock<std::mutex> lock(mutex);
    EXPECT_TRUE(cv.wait_for(lock, std::chrono::seconds(60), [&] { return done.size() == 2; }));
  }
  system.finish();
  return out;
}

}  // namespace

TEST(TrackingSlots, OneSlotHoldsTheOtherWorkersUntilTheBusyOneIsDone) {
  const Outcome o = run_with_slots(1);
  EXPECT_EQ(o.waiters_seen, 1u);
  EXPECT_FALSE(o.second_done_while_held);
}

TEST(TrackingSlots, WithoutALimitTheOtherWorkersGoOn) {
  const Outcome o = run_with_slots(0);
  EXPECT_EQ(o.waiters_seen, 0u);
  EXPECT_TRUE(o.second_done_while_held);
}
