// Query training's hot paths: sampling labelled pixels from one 512 x 128 x 192 feature map, and
// one optimisation pass (LSeg loss, Adam; single-threaded torch for determinism).
#include <benchmark/benchmark.h>

#include <random>

#if SLAMVDB_WITH_TRAINING
#include "slamvdb/training/query_trainer.hpp"

namespace {

using namespace slamvdb;

// Arg: 0 uniform, 1 class-balanced; 1024 pixels of a full-size map with 6 classes in bands.
void BM_SamplePixels(benchmark::State& state) {
  FeatureMap map(512, 128, 192);
  std::mt19937 rng(1);
  std::normal_distribution<float> g;
  for (float& v : map.values()) v = g(rng);
  std::vector<int> targets(128 * 192);
  for (std::size_t i = 0; i < targets.size(); ++i) targets[i] = static_cast<int>(i / 192 / 22);  // 6 bands
  const auto sampling = state.range(0) ? PixelSampling::kClassBalanced : PixelSampling::kUniform;
  for (auto _ : state) {
    PixelSamples samples(512);
    samples.reserve(1024);
    benchmark::DoNotOptimize(sample_pixels(map, targets, 1024, sampling, 7, samples));
  }
  state.SetItemsProcessed(state.iterations() * 1024);
}
BENCHMARK(BM_SamplePixels)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

// One epoch over 131 072 sampled pixels (128 images x 1024), 512-d, 6 classes, batch 4096.
void BM_TrainEpoch(benchmark::State& state) {
  constexpr int kDim = 512, kClasses = 6;
  PixelSamples samples(kDim);
  std::mt19937 rng(2);
  std::normal_distribution<float> g;
  std::vector<float> x(kDim);
  for (int i = 0; i < 131072; ++i) {
    for (float& v : x) v = g(rng);
    samples.append(x.data(), static_cast<int16_t>(i % kClasses));
  }
  QueryMatrix init(kClasses, kDim);
  for (int i = 0; i < init.size(); ++i) init.data()[i] = g(rng);
  QueryTrainer trainer(init, TrainerOptions{});
  for (auto _ : state) benchmark::DoNotOptimize(trainer.train_epoch(samples));
  state.SetItemsProcessed(state.iterations() * static_cast<int64_t>(samples.size()));
}
BENCHMARK(BM_TrainEpoch)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace
#endif
