// The simulated dense encoder at the paper's feature size (512 x 128 x 192, 50 MB per frame),
// writing into a fresh feature map per frame (Arg 0) or into one reused buffer (Arg 1), which is
// what the streaming mapper's inference thread does (FeatureSource::features_into); the second
// argument is the preset: 0 clean, 1 realistic (its failure modes cost extra passes per frame).
#include <benchmark/benchmark.h>

#include <opencv2/imgproc.hpp>
#include <string>

#include "slamvdb/inference/simulated_encoders.hpp"

namespace slamvdb {
namespace {

void BM_SimulatedDenseEncoder(benchmark::State& state) {
  // 512-d, 192 x 128
  const SimulatedEncoderConfig config =
      state.range(1) == 1 ? simulated_encoder_preset("realistic", {}) : SimulatedEncoderConfig::clean();
  SimulatedDenseEncoder encoder(config);
  ImageFrame frame;
  frame.labels = cv::Mat(400, 640, CV_8UC1, cv::Scalar(3));  // grass, with sky, trees and a trail
  cv::rectangle(frame.labels, {0, 0}, {639, 90}, cv::Scalar(7), cv::FILLED);
  cv::rectangle(frame.labels, {0, 90}, {319, 170}, cv::Scalar(4), cv::FILLED);
  cv::rectangle(frame.labels, {240, 170}, {400, 399}, cv::Scalar(1), cv::FILLED);
  const bool reuse = state.range(0) == 1;
  FeatureMap features;
  for (auto _ : state) {
    frame.stamp += 0.2;
    if (reuse) encoder.encode_into(frame, features);
    else features = encoder.encode(frame);
    benchmark::DoNotOptimize(features.values().data());
  }
  state.SetLabel(std::string(reuse ? "reused buffer" : "fresh feature map per frame") +
                 (state.range(1) == 1 ? ", realistic" : ", clean"));
}
BENCHMARK(BM_SimulatedDenseEncoder)
    ->ArgsProduct({{0, 1}, {0, 1}})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

}  // namespace
}  // namespace slamvdb
