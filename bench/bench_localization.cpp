// Localization hot paths: odometry per scan on a full-size 131k-point OS1-64 scan, ScanContext
// build + query, pose-graph solve.
#include <benchmark/benchmark.h>
#include <fmt/format.h>
#include <tbb/global_control.h>

#include <numbers>
#include <random>

#include "bench_data.hpp"
#include "slamvdb/localization/odometry.hpp"
#include "slamvdb/localization/pose_graph.hpp"
#include "slamvdb/localization/scan_context.hpp"

namespace slamvdb::bench {
namespace {

using namespace slamvdb::localization;

std::vector<Vec3f> moved(const std::vector<Vec3f>& scan, const Pose& T) {
  std::vector<Vec3f> out;
  out.reserve(scan.size());
  const Eigen::Isometry3f Tf = T.cast<float>();
  for (const Vec3f& p : scan) out.push_back(Tf * p);
  return out;
}

// Registers the real RELLIS-3D scan (131 072 points) against a local map built from it, the
// scan seen from 0.3 m / 1 degree away each iteration. Arg: threads.
void BM_OdometryRegisterScan(benchmark::State& state) {
  tbb::global_control threads(tbb::global_control::max_allowed_parallelism, static_cast<std::size_t>(state.range(0)));
  bool real = false;
  const std::vector<Vec3f> scan = benchmark_scan(&real);
  Pose step = Pose::Identity();
  step.linear() = Eigen::AngleAxisd(std::numbers::pi / 180.0, Vec3d::UnitZ()).toRotationMatrix();
  step.translation() = Vec3d(0.3, 0.05, 0.0);
  const std::vector<Vec3f> other = moved(scan, step.inverse());
  double stamp = 0.0;
  LidarOdometry odometry;
  odometry.register_scan(stamp, scan);
  std::size_t i = 0;
  for (auto _ : state) {
    stamp += 0.1;
    const auto r = odometry.register_scan(stamp, (i++ % 2) ? scan : other);
    benchmark::DoNotOptimize(r);
  }
  state.SetLabel(fmt::format("{} scan, {} points", real ? "RELLIS-3D" : "SIMULATED", scan.size()));
  state.counters["Hz"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_OdometryRegisterScan)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_ScanContextBuild(benchmark::State& state) {
  const std::vector<Vec3f> scan = benchmark_scan();
  std::vector<Vec3d> points;
  for (const Vec3f& p : scan) points.push_back(p.cast<double>());
  for (auto _ : state) benchmark::DoNotOptimize(make_scan_context(points, ScanContextConfig{}));
}
BENCHMARK(BM_ScanContextBuild)->Unit(benchmark::kMillisecond);

// A query against a database of 1000 keyframes (random descriptors of the same scan, rotated).
void BM_ScanContextQuery(benchmark::State& state) {
  const std::vector<Vec3f> scan = benchmark_scan();
  ScanContextDatabase db;
  std::vector<Vec3d> points;
  for (const Vec3f& p : scan) points.push_back(p.cast<double>());
  ScanContext base = make_scan_context(points, db.config());
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.0f, 0.5f);
  for (int k = 0; k < 1000; ++k) {
    ScanContext c = base;
    for (int i = 0; i < c.descriptor.size(); ++i) c.descriptor.data()[i] = std::max(0.0f, c.descriptor.data()[i] + noise(rng));
    c.ring_key = c.descriptor.rowwise().mean();
    c.sector_key = c.descriptor.colwise().mean().transpose();
    db.add(std::move(c));
  }
  db.query(base, db.size(), 10, 1.0);  // builds the tree once
  for (auto _ : state) benchmark::DoNotOptimize(db.query(base, db.size(), 10, 1.0));
}
BENCHMARK(BM_ScanContextQuery)->Unit(benchmark::kMillisecond);

// A 500-keyframe loop with drift and one loop edge.
void BM_PoseGraphSolve(benchmark::State& state) {
  for (auto _ : state) {
    state.PauseTiming();
    PoseGraph graph;
    Pose T = Pose::Identity();
    Pose step = Pose::Identity();
    step.linear() = Eigen::AngleAxisd(2.0 * std::numbers::pi / 500 + 0.001, Vec3d::UnitZ()).toRotationMatrix();
    step.translation() = Vec3d(2.0, 0.0, 0.0);
    graph.add_vertex(T);
    for (std::size_t i = 1; i < 500; ++i) {
      T = T * step;
      graph.add_vertex(T);
      graph.add_edge({i - 1, i, step, isotropic_information(0.04, 0.003), false});
    }
    graph.add_edge({0, 499, Pose::Identity(), isotropic_information(0.1, 0.01), true});
    state.ResumeTiming();
    benchmark::DoNotOptimize(graph.optimize());
  }
}
BENCHMARK(BM_PoseGraphSolve)->Unit(benchmark::kMillisecond);

}  // namespace
}  // namespace slamvdb::bench
