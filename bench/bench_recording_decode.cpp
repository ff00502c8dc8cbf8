// PointCloud2 message -> points and per-point times on one core (decode_point_cloud2 +
// extract_points into reused buffers), in GB/s of message bytes, beside a plain memcpy of the same
// bytes. The target: at least 1 GB/s. Clouds of 64 x 1024 and 64 x 2048 points in four
// layouts:
//   0 spec:   x y z intensity float32, t uint32; point_step 20 (the recording fixtures' layout)
//   1 ouster: Ouster's 48-byte points (x y z, pad, intensity, t, reflectivity, ring, ambient, range)
//   2 f64:    x y z and timestamp float64, point_step 32 (generic path)
//   3 be:     layout 0 big-endian (generic path, byte-swapped)
#include <benchmark/benchmark.h>

#include <cstring>
#include <string>
#include <vector>

#include "slamvdb/recording/point_cloud2.hpp"

namespace slamvdb {
namespace {

struct BenchField {
  const char* name;
  std::uint32_t offset;
  std::uint8_t datatype;
};

// A PointCloud2 in ROS 1 serialization (packed little-endian), with `rows` x `columns` points.
std::vector<std::uint8_t> ros1_cloud(int layout, int rows, int columns) {
  std::vector<BenchField> fields;
  std::uint32_t step = 20;
  if (layout == 0 || layout == 3) fields = {{"x", 0, 7}, {"y", 4, 7}, {"z", 8, 7}, {"intensity", 12, 7}, {"t", 16, 6}};
  if (layout == 1) {
    fields = {{"x", 0, 7},  {"y", 4, 7},  {"z", 8, 7},  {"intensity", 16, 7}, {"t", 20, 6},
              {"reflectivity", 24, 4}, {"ring", 26, 4}, {"ambient", 28, 4}, {"range", 32, 6}};
    step = 48;
  }
  if (layout == 2) {
    fields = {{"x", 0, 8}, {"y", 8, 8}, {"z", 16, 8}, {"timestamp", 24, 8}};
    step = 32;
  }
  const bool big_endian = layout == 3;
  std::vector<std::uint8_t> out;
  const auto put = [&](const void* p, std::size_t n) {
    const std::size_t at = out.size();
    out.resize(at + n);
    std::memcpy(out.data() + at, p, n);
  };
  const auto u32 = [&](std::uint32_t v) { put(&v, 4); };
  const auto str = [&](const std::string& s) {
    u32(static_cast<std::uint32_t>(s.size()));
    put(s.data(), s.size());
  };
  u32(1);
  u32(1700000000);
  u32(0);
  str("os_sensor");
  u32(rows);
  u32(columns);
  u32(static_cast<std::uint32_t>(fields.size()));
  for (const auto& f : fields) {
    str(f.name);
    u32(f.offset);
    out.push_back(f.datatype);
    u32(1);
  }
  out.push_back(big_endian);
  u32(step);
  u32(step * columns);
  const std::size_t n = static_cast<std::size_t>(rows) * columns;
  u32(static_cast<std::uint32_t>(n * step));
  std::vector<std::uint8_t> data(n * step, 0);
  for (std::size_t i = 0; i < n; ++i) {
    std::uint8_t* p = data.data() + i * step;
    const double values[4] = {std::cos(i * 0.001) * 10, std::sin(i * 0.001) * 10, 0.01 * (i % 64),
                              1700000000.0 + 1e-6 * static_cast<double>(i % columns)};
    for (const auto& f : fields) {
      const int axis = f.name[0] == 'x' ? 0 : f.name[0] == 'y' ? 1 : f.name[0] == 'z' ? 2 : f.name[1] == 'i' ? 3 : -1;
      if (f.datatype == 7 && axis >= 0) {
        float v = static_cast<float>(values[axis]);
        std::uint32_t bits;
        std::memcpy(&bits, &v, 4);
        if (big_endian) bits = __builtin_bswap32(bits);
        std::memcpy(p + f.offset, &bits, 4);
      } else if (f.datatype == 8) {
        std::memcpy(p + f.offset, &values[axis], 8);
      } else if (f.name == std::string("t")) {
        std::uint32_t t = static_cast<std::uint32_t>(1000 * (i % columns));
        if (big_endian) t = __builtin_bswap32(t);
        std::memcpy(p + f.offset, &t, 4);
      }
    }
  }
  put(data.data(), data.size());
  out.push_back(1);
  return out;
}

// Arguments: layout (see the top), columns.
void BM_PointCloud2ToPoints(benchmark::State& state) {
  const auto message = ros1_cloud(static_cast<int>(state.range(0)), 64, static_cast<int>(state.range(1)));
  std::vector<Vec3f> points;
  std::vector<float> times;
  for (auto _ : state) {
    const auto cloud = recording::decode_point_cloud2(message, recording::Serialization::kRos1);
    benchmark::DoNotOptimize(recording::extract_points(cloud, points, &times));
    benchmark::DoNotOptimize(points.data());
    benchmark::DoNotOptimize(times.data());
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * message.size()));
  state.counters["MB/message"] = static_cast<double>(message.size()) / 1e6;
}
BENCHMARK(BM_PointCloud2ToPoints)
    ->ArgsProduct({{0, 1, 2, 3}, {1024, 2048}})
    ->ArgNames({"layout", "columns"})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

// The physical reference: copying the same message bytes once.
void BM_PointCloud2Memcpy(benchmark::State& state) {
  const auto message = ros1_cloud(static_cast<int>(state.range(0)), 64, static_cast<int>(state.range(1)));
  std::vector<std::uint8_t> copy(message.size());
  for (auto _ : state) {
    std::memcpy(copy.data(), message.data(), message.size());
    benchmark::DoNotOptimize(copy.data());
    benchmark::ClobberMemory();
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * message.size()));
}
BENCHMARK(BM_PointCloud2Memcpy)
    ->ArgsProduct({{0, 1, 2}, {1024, 2048}})
    ->ArgNames({"layout", "columns"})
    ->Unit(benchmark::kMicrosecond)
    ->UseRealTime();

}  // namespace
}  // namespace slamvdb
