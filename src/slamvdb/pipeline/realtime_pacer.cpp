#include "slamvdb/pipeline/realtime_pacer.hpp"

#include <thread>

namespace slamvdb {

RealtimePacer::WallClock RealtimePacer::steady_clock() {
  return {[] { return Clock::now(); }, [](Clock::time_point t) { std::this_thread::sleep_until(t); }};
}

RealtimePacer::RealtimePacer(double first_stamp, WallClock clock)
    : clock_(std::move(clock)), first_stamp_(first_stamp), start_(clock_.now()) {}

RealtimePacer::Clock::time_point RealtimePacer::due(double stamp) const {
  return start_ + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(stamp - first_stamp_));
}

void RealtimePacer::wait_for(double stamp) const {
  const auto t = due(stamp);
  if (clock_.now() < t) clock_.sleep_until(t);
}

bool RealtimePacer::arrived(double stamp) const { return clock_.now() >= due(stamp); }

double RealtimePacer::elapsed() const { return std::chrono::duration<double>(clock_.now() - start_).count(); }

}  // namespace slamvdb
