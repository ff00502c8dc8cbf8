// The real-time replay clock on a simulated wall clock: a stamp is due its offset from the first
// stamp after the start, waits end there, and what has "arrived" follows the clock.
#include "slamvdb/pipeline/realtime_pacer.hpp"

#include <gtest/gtest.h>

#include <vector>

namespace slamvdb {
namespace realtime_pacer_test {

using Clock = RealtimePacer::Clock;

struct SimulatedClock {
  Clock::time_point now{std::chrono::seconds(1000)};
  std::vector<double> sleeps;  // seconds slept, one per sleep
  RealtimePacer::WallClock wall() {
    return {[this] { return now; },
            [this](Clock::time_point t) {
              sleeps.push_back(std::chrono::duration<double>(t - now).count());
              now = t;
            }};
  }
  void advance(double seconds) { now += std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(seconds)); }
};

TEST(RealtimePacer, WaitsUntilEachStampIsDueAndNeverForAPastOne) {
  SimulatedClock clock;
  const RealtimePacer pacer(1700000000.0, clock.wall());
  pacer.wait_for(1700000000.0);  // due at the start: no sleep
  EXPECT_TRUE(clock.sleeps.empty());
  pacer.wait_for(1700000000.25);
  ASSERT_EQ(clock.sleeps.size(), 1u);
  EXPECT_NEAR(clock.sleeps[0], 0.25, 1e-6);
  EXPECT_NEAR(pacer.elapsed(), 0.25, 1e-6);
  clock.advance(1.0);  // the work took longer than the data's time: later frames are late
  pacer.wait_for(1700000000.5);
  EXPECT_EQ(clock.sleeps.size(), 1u);
  EXPECT_NEAR(pacer.elapsed(), 1.25, 1e-6);
}

TEST(RealtimePacer, AFrameHasArrivedOnceItsStampIsDue) {
  SimulatedClock clock;
  const RealtimePacer pacer(10.0, clock.wall());
  EXPECT_TRUE(pacer.arrived(10.0));
  EXPECT_FALSE(pacer.arrived(10.1));
  clock.advance(0.1);
  EXPECT_TRUE(pacer.arrived(10.1));
  EXPECT_FALSE(pacer.arrived(10.2));
  EXPECT_DOUBLE_EQ(pacer.first_stamp(), 10.0);
}

}  // namespace realtime_pacer_test
}  // namespace slamvdb
