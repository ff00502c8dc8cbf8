// ComputeGate (compute_gate.hpp): at most `slots` holders at once, the others admitted in the order
// they came, and a waiter whose deadline passes leaves the queue without taking or losing a slot.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <mutex>
#include <optional>
#include <thread>
#include <vector>

#include "slamvdb/server/compute_gate.hpp"

namespace slamvdb {
namespace {

// Waits (bounded) until `gate` has `n` queued requests.
void wait_for_queue(const ComputeGate& gate, std::size_t n) {
  const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(20);
  while (gate.waiting() != n && std::chrono::steady_clock::now() < give_up) std::this_thread::yield();
  ASSERT_EQ(gate.waiting(), n);
}

TEST(ComputeGate, WaitersAreAdmittedInTheOrderTheyCame) {
  ComputeGate gate(2);
  EXPECT_EQ(gate.slots(), 2u);
  std::optional<ComputeGate::Pass> first(gate.enter()), second(gate.enter());
  EXPECT_EQ(gate.computing(), 2u);
  std::mutex m;
  std::vector<int> order;
  std::vector<std::thread> threads;
  constexpr int kWaiters = 6;
  for (int i = 0; i < kWaiters; ++i) {
    threads.emplace_back([&, i] {
      const ComputeGate::Pass pass = gate.enter();
      const std::lock_guard lock(m);
      order.push_back(i);
    });
    wait_for_queue(gate, static_cast<std::size_t>(i) + 1);  // i is queued before i + 1 comes
  }
  EXPECT_EQ(gate.computing(), 2u) << "nobody entered past the two holders";
  first.reset();  // one slot for the queue (the other stays held): they pass one at a time
  for (std::thread& t : threads) t.join();
  EXPECT_EQ(order, (std::vector<int>{0, 1, 2, 3, 4, 5}));
  EXPECT_EQ(gate.computing(), 1u);
  second.reset();
  EXPECT_EQ(gate.computing(), 0u);
  EXPECT_EQ(gate.waiting(), 0u);
}

TEST(ComputeGate, NeverMoreThanItsSlotsAtOnce) {
  ComputeGate gate(2);
  std::atomic<int> inside{0}, most{0};
  std::vector<std::thread> threads;
  for (int i = 0; i < 8; ++i)
    threads.emplace_back([&] {
      for (int r = 0; r < 3; ++r) {
        const ComputeGate::Pass pass = gate.enter();
        const int now = ++inside;
        int seen = most.load();
        while (now > seen && !most.compare_exchange_weak(seen, now)) {
        }
        std::this_thread::sleep_for(std::chrono::milliseconds(1));
        --inside;
      }
    });
  for (std::thread& t : threads) t.join();
  EXPECT_LE(most.load(), 2);
  EXPECT_GE(most.load(), 1);
  EXPECT_EQ(gate.computing(), 0u);
}

TEST(ComputeGate, AWaiterPastItsDeadlineLeavesTheQueueAndTheSlotGoesToTheNext) {
  ComputeGate gate(1);
  std::optional<ComputeGate::Pass> holder(gate.enter());
  std::atomic<bool> timed_out{false}, later_entered{false};
  std::thread impatient([&] {
    try {
      const ComputeGate::Pass pass = gate.enter(Deadline::after(std::chrono::milliseconds(30)));
    } catch (const DeadlineExceeded& e) {
      timed_out = std::string(e.what()).find("waiting for a free core") != std::string::npos;
    }
  });
  wait_for_queue(gate, 1);
  std::thread patient([&] {
    const ComputeGate::Pass pass = gate.enter();
    later_entered = true;
  });
  impatient.join();
  EXPECT_TRUE(timed_out);
  wait_for_queue(gate, 1);  // the impatient one left, the patient one waits
  EXPECT_FALSE(later_entered);
  holder.reset();
  patient.join();
  EXPECT_TRUE(later_entered);
  EXPECT_EQ(gate.computing(), 0u);
  EXPECT_EQ(gate.waiting(), 0u);
  { const ComputeGate::Pass again = gate.enter(Deadline::after(std::chrono::milliseconds(1))); }  // a free slot: at once
}

TEST(ComputeGate, ZeroSlotsMeansTheHardwareThreads) {
  EXPECT_EQ(ComputeGate(0).slots(), std::max<std::size_t>(1, std::thread::hardware_concurrency()));
}

}  // namespace
}  // namespace slamvdb
