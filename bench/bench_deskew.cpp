// Deskewing a scan before fusion (pipeline/scan_deskew.hpp), once per scan with per-point times:
// a full-size OS1-64 scan (the real RELLIS-3D one when ../shared is there: 77 708 valid points) swept over
// 0.1 s by azimuth, as a spinning LiDAR takes it. With the trajectory (map with poses: a pose
// topic at 100 Hz, 11 poses inside the sweep) and with the odometry's sweep motion (slam).
#include <benchmark/benchmark.h>
#include <fmt/format.h>

#include <cmath>
#include <numbers>

#include "bench_data.hpp"
#include "slamvdb/pipeline/scan_deskew.hpp"

namespace slamvdb::bench {
namespace {

// Seconds from the scan's stamp by azimuth: one turn in 0.1 s.
std::vector<float> sweep_times(const std::vector<Vec3f>& scan) {
  std::vector<float> times;
  times.reserve(scan.size());
  for (const Vec3f& p : scan)
    times.push_back(static_cast<float>((std::atan2(p.y(), p.x()) + std::numbers::pi) / (2 * std::numbers::pi) * 0.1));
  return times;
}

// 5 m/s forward, turning at 90 deg/s.
Pose motion_at(double t) {
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(t * std::numbers::pi / 2, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = Vec3d(5.0 * t, 0.0, 0.0);
  return T;
}

void BM_DeskewWithTrajectory(benchmark::State& state) {
  bool real = false;
  const std::vector<Vec3f> scan = benchmark_scan(&real);
  const std::vector<float> times = sweep_times(scan);
  std::vector<double> stamps;
  std::vector<Pose> poses;
  for (int i = -2; i <= 12; ++i) stamps.push_back(i * 0.01), poses.push_back(motion_at(i * 0.01));
  const Trajectory trajectory(stamps, poses);
  std::vector<Vec3f> points;
  for (auto _ : state) {
    state.PauseTiming();
    points = scan;
    state.ResumeTiming();
    benchmark::DoNotOptimize(deskew_with_trajectory(trajectory, 0.0, points, times));
  }
  state.SetLabel(fmt::format("{} scan, {} points", real ? "RELLIS-3D" : "SIMULATED", scan.size()));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * scan.size()));
}
BENCHMARK(BM_DeskewWithTrajectory)->Unit(benchmark::kMillisecond);

void BM_DeskewWithSweep(benchmark::State& state) {
  bool real = false;
  const std::vector<Vec3f> scan = benchmark_scan(&real);
  const std::vector<float> times = sweep_times(scan);
  const localization::SweepMotion sweep =
      localization::sweep_motion(std::vector<double>(times.begin(), times.end()), motion_at(0.1));
  std::vector<Vec3f> points;
  for (auto _ : state) {
    state.PauseTiming();
    points = scan;
    state.ResumeTiming();
    deskew_with_sweep(sweep, points, times);
    benchmark::DoNotOptimize(points.data());
  }
  state.SetLabel(fmt::format("{} scan, {} points", real ? "RELLIS-3D" : "SIMULATED", scan.size()));
  state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * scan.size()));
}
BENCHMARK(BM_DeskewWithSweep)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace slamvdb::bench
