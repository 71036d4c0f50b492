// FifoSlots: at most N holders, waiters served in arrival order; a lent slot is taken back first.
#include <atomic>
#include <mutex>
#include <thread>
#include <vector>

#include <gtest/gtest.h>

#include "core/fifo_slots.h"

using cslam::FifoSlots;

namespace {

void wait_for_waiters(const FifoSlots& slots, std::size_t n) {
  while (slots.waiting() < n) std::this_thread::yield();
}

}  // namespace

TEST(FifoSlots, ServesWaitersInArrivalOrder) {
  FifoSlots slots(1);
  std::mutex m;
  std::vector<int> order;
  std::vector<std::thread> threads;
  {
    const FifoSlots::Hold first(&slots);
    for (int i = 0; i < 4; ++i) {
      threads.emplace_back([&, i] {
        const FifoSlots::Hold hold(&slots);
        std::lock_guard<std::mutex> lock(m);
        order.push_back(i);
      });
      wait_for_waiters(slots, std::size_t(i + 1));  // thread i waits before thread i + 1 starts
    }
    EXPECT_EQ(slots.waiting(), 4u);
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3}));
  EXPECT_EQ(slots.waiting(), 0u);
}

TEST(FifoSlots, NeverMoreHoldersThanSlots) {
  constexpr int kSlots = 2, kThreads = 6, kRounds = 2000;
  FifoSlots slots(kSlots);
  std::atomic<int> inside{0}, most{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t)
    threads.emplace_back([&] {
      for (int r = 0; r < kRounds; ++r) {
        const FifoSlots::Hold hold(&slots);
        const int now = ++inside;
        int seen = most.load();
        while (now > seen && !most.compare_exchange_weak(seen, now)) {
        }
        --inside;
      }
    });
  for (auto& t : threads) t.join();
  EXPECT_LE(most.load(), kSlots);
  EXPECT_GE(most.load(), 1);
  EXPECT_EQ(slots.waiting(), 0u);
}

TEST(FifoSlots, SecondSlotServesAWaiterWhileTheFirstIsHeld) {
  FifoSlots slots(2);
  const FifoSlots::Hold a(&slots);
  std::thread t([&] { const FifoSlots::Hold b(&slots); });  // must not block: one slot is free
  t.join();
  EXPECT_EQ(slots.waiting(), 0u);
}

// A holder that lends its slot while it waits lets the next waiter in, and taking it back goes
// before a thread that arrived later (its frame is half done).
TEST(FifoSlots, LentSlotServesAWaiterAndIsTakenBackBeforeNewcomers) {
  FifoSlots slots(1);
  FifoSlots::Hold a(&slots);
  std::mutex m;
  std::vector<char> order;
  std::atomic<bool> b_in{false}, b_may_leave{false};
  std::thread b([&] {
    const FifoSlots::Hold hold(&slots);
    b_in = true;
    while (!b_may_leave) std::this_thread::yield();
    std::lock_guard<std::mutex> lock(m);
    order.push_back('b');
  });
  wait_for_waiters(slots, 1);
  a.lend();
  while (!b_in) std::this_thread::yield();  // b got the lent slot
  std::thread c([&] {
    const FifoSlots::Hold hold(&slots);
    std::lock_guard<std::mutex> lock(m);
    order.push_back('c');
  });
  wait_for_waiters(slots, 1);  // c waits behind b's slot
  std::thread back([&] {
    a.take_back();
    {
      std::lock_guard<std::mutex> lock(m);
      order.push_back('a');
    }
    a.lend();  // a's frame is done: its slot goes to c
  });
  wait_for_waiters(slots, 2);  // a returning and c new, both waiting for b's slot
  b_may_leave = true;
  b.join();
  back.join();
  c.join();
  EXPECT_EQ(order, (std::vector<char>{'b', 'a', 'c'}));
  EXPECT_EQ(slots.waiting(), 0u);
}

TEST(FifoSlots, ALentSlotIsNotReleasedTwice) {
  FifoSlots slots(1);
  {
    FifoSlots::Hold a(&slots);
    a.lend();
  }  // the destructor must not release the lent slot a second time
  std::atomic<bool> got{false};
  std::thread t;
  {
    const FifoSlots::Hold b(&slots);
    t = std::thread([&] {
      const FifoSlots::Hold c(&slots);
      got = true;
    });
    while (slots.waiting() == 0 && !got) std::this_thread::yield();
    EXPECT_FALSE(got.load()) << "two holders of one slot";
  }
  t.join();
  EXPECT_TRUE(got.load());
}
