// A TorchScript dense encoder whose output tensor is Half (a network run in half precision) hands
// fusion fp16 feature maps, not widened ones. The model is scripted here in C++ (no Python needed).
#include <gtest/gtest.h>
#include <torch/script.h>

#include <cmath>
#include <fstream>
#include <random>

#include "slamvdb/inference/torch_encoders.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;

constexpr int kHalfTestDim = 12, kHalfTestH = 8, kHalfTestW = 12;

// half.pt (every other pixel of the input, in four channel groups, returned as Half) and its manifest.
fs::path write_half_model(const fs::path& dir, bool normalize_output) {
  torch::jit::Module m("HalfDense");
  m.define(R"(
def forward(self, x):
    y = x[:, :, ::2, ::2]
    return torch.cat([y, 2.0 * y - 1.0, y * y, y + 0.5], 1).half()
)");
  const std::string name = normalize_output ? "half_normalized" : "half";
  m.save((dir / (name + ".pt")).string());
  std::ofstream(dir / (name + ".json")) << R"({
    "manifest_version": 1, "kind": "dense_image", "model_id": "half-test",
    "input": {"height": 16, "width": 24, "resize": "resize", "interpolation": "area",
              "channel_order": "RGB", "value_scale": 0.00392156862745098,
              "mean": [0.5, 0.5, 0.5], "std": [0.5, 0.25, 0.5]},
    "output": {"dim": 12, "height": 8, "width": 12, "layout": "CHW",
               "l2_normalized": false, "normalize_output": )"
                                        << (normalize_output ? "true" : "false") << R"(},
    "runtime": {"threads": 1, "batch_size": 2}})";
  return dir / (name + ".pt");
}

ImageFrame random_frame(uint32_t seed) {
  ImageFrame f;
  f.rgb = cv::Mat(16, 24, CV_8UC3);
  std::mt19937 rng(seed);
  for (int y = 0; y < 16; ++y)
    for (int x = 0; x < 24; ++x)
      for (int c = 0; c < 3; ++c) f.rgb.at<cv::Vec3b>(y, x)[c] = static_cast<uint8_t>(rng() % 256);
  f.source = "random" + std::to_string(seed);
  return f;
}

TEST(TorchHalfOutput, DenseEncoderHandsOverTheHalfTensorBitForBit) {
  testing::TempDir tmp;
  const fs::path model = write_half_model(tmp.path, false);
  TorchDenseImageEncoder encoder(model);
  const ImageFrame frame = random_frame(1);
  const FeatureMap f = encoder.encode(frame);
  ASSERT_EQ(f.precision(), EmbeddingPrecision::kFloat16);
  ASSERT_EQ(f.dim(), kHalfTestDim);
  ASSERT_EQ(f.height(), kHalfTestH);
  ASSERT_EQ(f.width(), kHalfTestW);

  // The same module run here: its Half output, transposed to pixel-major, bit for bit.
  at::Tensor input = torch::empty({1, 3, 16, 24}, torch::kFloat);
  image_to_network_input(frame, encoder.manifest(), input.data_ptr<float>());
  torch::jit::Module m = torch::jit::load(model.string());
  const at::Tensor expected = m.forward({input}).toTensor().contiguous();
  ASSERT_EQ(expected.scalar_type(), torch::kHalf);
  const auto* e = reinterpret_cast<const uint16_t*>(expected.data_ptr<at::Half>());
  for (int c = 0; c < kHalfTestDim; ++c)
    for (int y = 0; y < kHalfTestH; ++y)
      for (int x = 0; x < kHalfTestW; ++x)
        ASSERT_EQ(f.half_pixel(x, y)[c], e[(c * kHalfTestH + y) * kHalfTestW + x]) << c << " " << y << " " << x;

  // A batch gives the same maps, in fp16 too.
  const std::vector<FeatureMap> batch = encoder.encode_batch({frame, random_frame(2), frame});
  ASSERT_EQ(batch.size(), 3u);
  EXPECT_EQ(batch[0], f);
  EXPECT_EQ(batch[2], f);
  EXPECT_NE(batch[1], f);
}

TEST(TorchHalfOutput, NormalizedHalfOutputStaysHalfWithUnitPixels) {
  testing::TempDir tmp;
  TorchDenseImageEncoder encoder(write_half_model(tmp.path, true));
  const FeatureMap f = encoder.encode(random_frame(3));
  ASSERT_EQ(f.precision(), EmbeddingPrecision::kFloat16);
  std::vector<float> v(kHalfTestDim);
  for (int y = 0; y < kHalfTestH; ++y)
    for (int x = 0; x < kHalfTestW; ++x) {
      f.decode_pixel(x, y, v.data());
      double n2 = 0;
      for (float a : v) n2 += static_cast<double>(a) * a;
      EXPECT_NEAR(std::sqrt(n2), 1.0, 2e-3) << x << " " << y;
    }
}

}  // namespace
}  // namespace slamvdb
