// Frames per second of the dense encoder at the paper's settings: a ViT-B/16-sized, LSeg-shaped
// network (12 layers, width 768, 12 heads, patch 16, DPT fusion head) on a 256 x 384 input ->
// 512 x 128 x 192 unit features, through the TorchScript backend on the CPU. The weights are
// random (the real ones cannot be downloaded here); the cost is that of a real network this size.
// The model is built once by tools/make_test_models.py --vit-b16 into $SLAMVDB_MODEL_CACHE
// (default: <tmp>/slamvdb-bench-models). The frame is the real RELLIS-3D image when present.
// Thread counts interact with OpenBLAS's own pool (used for the transformer's matmuls): with
// 2 threads, OMP_WAIT_POLICY=passive stops the two pools spinning against each other.
#ifdef SLAMVDB_WITH_TORCH
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "slamvdb/inference/torch_encoders.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;

fs::path cache_dir() {
  if (const char* env = std::getenv("SLAMVDB_MODEL_CACHE")) return env;
  return fs::temp_directory_path() / "slamvdb-bench-models";
}

// The ViT-B/16 model's path, built with Python when missing; empty if that is impossible.
fs::path vit_b16_model() {
  const fs::path model = cache_dir() / "vitb16_dense.pt";
  if (fs::exists(model) && fs::exists(cache_dir() / "vitb16_dense.json")) return model;
  const std::string script = (fs::path(SLAMVDB_SOURCE_DIR) / "tools" / "make_test_models.py").string();
  for (const std::string python : {"python3", "/usr/bin/python3"}) {
    if (std::system((python + " -c 'import torch' >/dev/null 2>&1").c_str()) != 0) continue;
    const std::string cmd = python + " '" + script + "' --vit-b16 --out '" + cache_dir().string() + "'";
    if (std::system(cmd.c_str()) == 0) return model;
  }
  return {};
}

ImageFrame bench_frame() {
  ImageFrame frame;
  frame.source = (fs::path(SLAMVDB_SOURCE_DIR) / ".." / "shared" / "fixtures" / "rellis3d-000104" /
                  "frame000104-1581624663_149.jpg")
                     .string();
  const cv::Mat bgr = cv::imread(frame.source, cv::IMREAD_COLOR);
  if (bgr.empty()) {
    frame.rgb = cv::Mat(1200, 1920, CV_8UC3);
    cv::randu(frame.rgb, 0, 255);
    frame.source = "random 1920 x 1200 image";
  } else {
    cv::cvtColor(bgr, frame.rgb, cv::COLOR_BGR2RGB);
  }
  return frame;
}

// Arg: libtorch intra-op threads.
void BM_DenseEncoderViTB16(benchmark::State& state) {
  const fs::path model = vit_b16_model();
  if (model.empty()) {
    state.SkipWithError("no python3 with torch to build the ViT-B/16 benchmark model");
    return;
  }
  TorchDenseImageEncoder encoder(model, {.threads = static_cast<int>(state.range(0)), .warm_up = true});
  const ImageFrame frame = bench_frame();
  encoder.encode(frame);  // the TorchScript executor optimises on its second run
  FeatureMap features;
  for (auto _ : state) benchmark::DoNotOptimize(features = encoder.encode(frame));
  state.counters["fps"] = benchmark::Counter(static_cast<double>(state.iterations()), benchmark::Counter::kIsRate);
  state.SetLabel(std::to_string(features.dim()) + " x " + std::to_string(features.height()) + " x " +
                 std::to_string(features.width()) + " from " + std::to_string(frame.rgb.cols) + " x " +
                 std::to_string(frame.rgb.rows));
}
BENCHMARK(BM_DenseEncoderViTB16)->Arg(2)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime()->MinTime(5.0);

}  // namespace
}  // namespace slamvdb
#endif  // SLAMVDB_WITH_TORCH
