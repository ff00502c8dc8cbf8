#include "slamvdb/inference/model_manifest.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

json dense_json() {
  return json::parse(R"({
    "manifest_version": 1, "kind": "dense_image", "model_id": "lseg-test",
    "input": {"height": 256, "width": 384, "resize": "resize", "interpolation": "area",
              "channel_order": "RGB", "value_scale": 0.00392156862745098,
              "mean": [0.5, 0.5, 0.5], "std": [0.5, 0.25, 0.5]},
    "output": {"dim": 512, "height": 128, "width": 192, "layout": "CHW",
               "l2_normalized": true, "normalize_output": false},
    "runtime": {"threads": 2, "batch_size": 4}})");
}

json text_json() {
  return json::parse(R"({
    "manifest_version": 1, "kind": "text", "model_id": "clip-text",
    "text": {"context_length": 77, "vocab": "bpe_simple_vocab_16e6.txt.gz"},
    "output": {"dim": 512, "l2_normalized": false, "normalize_output": true}})");
}

ModelManifest parse(const json& j) { return parse_model_manifest(j.dump(), "/models/m.json"); }

// Expects parsing to fail with a message that names the file and contains `needle`.
void expect_rejected(const json& j, const std::string& needle) {
  try {
    parse(j);
    ADD_FAILURE() << "accepted: " << j.dump();
  } catch (const Error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("/models/m.json"), std::string::npos) << what;
    EXPECT_NE(what.find(needle), std::string::npos) << "expected '" << needle << "' in: " << what;
  }
}

TEST(ModelManifest, ParsesEveryDenseField) {
  const ModelManifest m = parse(dense_json());
  EXPECT_EQ(m.kind, ModelKind::kDenseImage);
  EXPECT_EQ(m.model_id, "lseg-test");
  EXPECT_EQ(m.model_path, fs::path("/models/m.pt"));
  EXPECT_EQ(m.input.height, 256);
  EXPECT_EQ(m.input.width, 384);
  EXPECT_EQ(m.input.resize, ResizePolicy::kResize);
  EXPECT_EQ(m.input.interpolation, cv::INTER_AREA);
  EXPECT_FALSE(m.input.bgr);
  EXPECT_FLOAT_EQ(m.input.value_scale, 1.0f / 255.0f);
  EXPECT_FLOAT_EQ(m.input.std[1], 0.25f);
  EXPECT_EQ(m.output.dim, 512);
  EXPECT_EQ(m.output.height, 128);
  EXPECT_EQ(m.output.width, 192);
  EXPECT_TRUE(m.output.l2_normalized);
  EXPECT_FALSE(m.output.normalize_output);
  EXPECT_EQ(m.threads, 2);
  EXPECT_EQ(m.batch_size, 4);
}

TEST(ModelManifest, TextVocabIsRelativeToTheManifestAndRuntimeDefaults) {
  const ModelManifest m = parse(text_json());
  EXPECT_EQ(m.kind, ModelKind::kText);
  EXPECT_EQ(m.text.context_length, 77);
  EXPECT_EQ(m.text.vocab, fs::path("/models/bpe_simple_vocab_16e6.txt.gz"));
  EXPECT_TRUE(m.output.normalize_output);
  EXPECT_EQ(m.threads, 0);
  EXPECT_EQ(m.batch_size, 1);
  json absolute = text_json();
  absolute["text"]["vocab"] = "/shared/clip/vocab.gz";
  EXPECT_EQ(parse(absolute).text.vocab, fs::path("/shared/clip/vocab.gz"));
}

TEST(ModelManifest, RejectsEveryKindOfBadField) {
  const auto with = [](json j, const json::json_pointer& p, const json& v) {
    j[p] = v;
    return j;
  };
  const auto without = [](json j, const json::json_pointer& p) {
    j[p.parent_pointer()].erase(p.back());
    return j;
  };
  using P = json::json_pointer;
  expect_rejected(without(dense_json(), P("/kind")), "'kind' is missing");
  expect_rejected(with(dense_json(), P("/kind"), "segmenter"), "'kind' must be one of");
  expect_rejected(with(dense_json(), P("/manifest_version"), 2), "'manifest_version'");
  expect_rejected(with(dense_json(), P("/model_id"), ""), "'model_id' must be a non-empty string");
  expect_rejected(without(dense_json(), P("/input/height")), "'input.height' is missing");
  expect_rejected(with(dense_json(), P("/input/width"), -3), "'input.width' must be an integer");
  expect_rejected(with(dense_json(), P("/input/width"), 3.5), "'input.width' must be an integer");
  expect_rejected(with(dense_json(), P("/input/resize"), "stretch"), "'input.resize' must be one of");
  expect_rejected(with(dense_json(), P("/input/interpolation"), "lanczos"), "'input.interpolation'");
  expect_rejected(with(dense_json(), P("/input/channel_order"), "rgb"), "'input.channel_order'");
  expect_rejected(with(dense_json(), P("/input/value_scale"), 0), "'input.value_scale' must be a positive number");
  expect_rejected(with(dense_json(), P("/input/mean"), json::array({0.5, 0.5})), "'input.mean' must be an array of 3");
  expect_rejected(with(dense_json(), P("/input/std"), json::array({0.5, 0.0, 0.5})),
                  "'input.std' must be an array of 3 positive");
  expect_rejected(with(dense_json(), P("/input/meen"), json::array({0.5, 0.5, 0.5})),
                  "'input.meen' is not a known field");
  expect_rejected(with(dense_json(), P("/output/dim"), 0), "'output.dim' must be an integer");
  expect_rejected(without(dense_json(), P("/output/height")), "'output.height' is missing");
  expect_rejected(with(dense_json(), P("/output/layout"), "HWC"), "'output.layout' must be one of \"CHW\"");
  expect_rejected(with(dense_json(), P("/output/l2_normalized"), "yes"),
                  "'output.l2_normalized' must be true or false");
  expect_rejected(without(dense_json(), P("/output/normalize_output")), "'output.normalize_output' is missing");
  expect_rejected(with(dense_json(), P("/runtime/threads"), -1), "'runtime.threads'");
  expect_rejected(with(dense_json(), P("/runtime/batch_size"), 0), "'runtime.batch_size'");
  expect_rejected(with(dense_json(), P("/runtime"), 4), "'runtime' must be an object");
  expect_rejected(with(dense_json(), P("/text"), text_json()["text"]), "'text' is not a known field");
  expect_rejected(with(text_json(), P("/output/height"), 4), "'output.height' is not a known field");
  expect_rejected(without(text_json(), P("/text/vocab")), "'text.vocab' is missing");
  expect_rejected(without(text_json(), P("/text")), "'text' is missing");
  json image = dense_json();
  image["kind"] = "image";
  expect_rejected(image, "'output.height' is not a known field");

  EXPECT_THROW(parse_model_manifest("{\"kind\": ", "/models/m.json"), Error);
  EXPECT_THROW(parse_model_manifest("[1, 2]", "/models/m.json"), Error);
}

TEST(ModelManifest, LoadFindsTheManifestBesideTheModelAndReportsAMissingOne) {
  const fs::path dir = fs::temp_directory_path() / ("slamvdb_manifest_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "lseg.json") << dense_json().dump();
  EXPECT_EQ(load_model_manifest(dir / "lseg.pt").model_id, "lseg-test");
  EXPECT_EQ(load_model_manifest(dir / "lseg.json").model_path, dir / "lseg.pt");
  try {
    load_model_manifest(dir / "other.pt");
    ADD_FAILURE() << "missing manifest accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find((dir / "other.json").string()), std::string::npos) << e.what();
  }
  fs::remove_all(dir);
}

ImageInputSpec spec(int width, int height, ResizePolicy policy) {
  ImageInputSpec s;
  s.width = width;
  s.height = height;
  s.resize = policy;
  return s;
}

TEST(ModelManifest, ResizePlansFollowThePolicy) {
  EXPECT_THROW(plan_resize({100, 50}, spec(96, 64, ResizePolicy::kExact), "a.png"), Error);
  const ResizePlan exact = plan_resize({96, 64}, spec(96, 64, ResizePolicy::kExact), "a.png");
  EXPECT_EQ(exact.scaled, cv::Size(96, 64));
  EXPECT_EQ(exact.crop, cv::Rect(0, 0, 96, 64));

  const ResizePlan stretch = plan_resize({1920, 1200}, spec(384, 256, ResizePolicy::kResize), "a.png");
  EXPECT_EQ(stretch.scaled, cv::Size(384, 256));
  EXPECT_EQ(stretch.crop, cv::Rect(0, 0, 384, 256));

  // CLIP: short side to 224, long side truncated (1920 * 224 / 1200 = 358.4), centred crop.
  const auto clip = spec(224, 224, ResizePolicy::kResizeShortCenterCrop);
  const ResizePlan landscape = plan_resize({1920, 1200}, clip, "a.png");
  EXPECT_EQ(landscape.scaled, cv::Size(358, 224));
  EXPECT_EQ(landscape.crop, cv::Rect(67, 0, 224, 224));
  const ResizePlan portrait = plan_resize({300, 500}, clip, "a.png");
  EXPECT_EQ(portrait.scaled, cv::Size(224, 373));
  EXPECT_EQ(portrait.crop, cv::Rect(0, 74, 224, 224));  // (373 - 224) / 2 = 74.5 -> 74, half to even
  // Non-square target: the image must cover both sides.
  const ResizePlan wide = plan_resize({400, 400}, spec(200, 100, ResizePolicy::kResizeShortCenterCrop), "a.png");
  EXPECT_EQ(wide.scaled, cv::Size(200, 200));
  EXPECT_EQ(wide.crop, cv::Rect(0, 50, 200, 100));
  // Python's round() as in torchvision: 0.5 -> 0, 1.5 -> 2.
  EXPECT_EQ(plan_resize({33, 32}, spec(32, 32, ResizePolicy::kResizeShortCenterCrop), "a").crop.x, 0);
  EXPECT_EQ(plan_resize({35, 32}, spec(32, 32, ResizePolicy::kResizeShortCenterCrop), "a").crop.x, 2);
}

ModelManifest image_manifest(int width, int height, ResizePolicy policy, bool bgr) {
  ModelManifest m;
  m.input = spec(width, height, policy);
  m.input.interpolation = cv::INTER_LINEAR;
  m.input.bgr = bgr;
  m.input.value_scale = 0.5f;
  m.input.mean = {1.0f, 2.0f, 3.0f};
  m.input.std = {2.0f, 4.0f, 8.0f};
  return m;
}

cv::Mat test_image(int width, int height) {
  cv::Mat rgb(height, width, CV_8UC3);
  for (int y = 0; y < height; ++y)
    for (int x = 0; x < width; ++x) rgb.at<cv::Vec3b>(y, x) = cv::Vec3b(10 * x + y, 100 + y, 200 - x);
  return rgb;
}

float expected_value(const ModelManifest& m, int channel, uint8_t pixel) {
  return (pixel * m.input.value_scale - m.input.mean[channel]) / m.input.std[channel];
}

TEST(ModelManifest, NetworkInputIsPlanarScaledAndNormalisedInTheManifestsChannelOrder) {
  ImageFrame frame;
  frame.rgb = test_image(3, 2);
  for (const bool bgr : {false, true}) {
    const ModelManifest m = image_manifest(3, 2, ResizePolicy::kExact, bgr);
    std::vector<float> chw(3 * 2 * 3);
    image_to_network_input(frame, m, chw.data());
    for (int c = 0; c < 3; ++c)
      for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 3; ++x) {
          const uint8_t pixel = frame.rgb.at<cv::Vec3b>(y, x)[bgr ? 2 - c : c];
          EXPECT_NEAR(chw[(c * 2 + y) * 3 + x], expected_value(m, c, pixel), 1e-6) << c << y << x << bgr;
        }
  }
}

TEST(ModelManifest, NetworkInputResizesAndCropsAsPlanned) {
  ImageFrame frame;
  frame.rgb = test_image(12, 8);
  // Centre crop without scaling: columns 2..9 of the original.
  const ModelManifest crop = image_manifest(8, 8, ResizePolicy::kResizeShortCenterCrop, false);
  std::vector<float> chw(3 * 8 * 8);
  image_to_network_input(frame, crop, chw.data());
  EXPECT_NEAR(chw[0], expected_value(crop, 0, frame.rgb.at<cv::Vec3b>(0, 2)[0]), 1e-6);
  EXPECT_NEAR(chw[8 * 8 + 7], expected_value(crop, 1, frame.rgb.at<cv::Vec3b>(0, 9)[1]), 1e-6);
  // Stretch: the same pixels cv::resize gives with the manifest's interpolation.
  const ModelManifest stretch = image_manifest(6, 3, ResizePolicy::kResize, false);
  cv::Mat expected;
  cv::resize(frame.rgb, expected, {6, 3}, 0, 0, cv::INTER_LINEAR);
  std::vector<float> small(3 * 3 * 6);
  image_to_network_input(frame, stretch, small.data());
  for (int y = 0; y < 3; ++y)
    for (int x = 0; x < 6; ++x)
      EXPECT_NEAR(small[2 * 18 + y * 6 + x], expected_value(stretch, 2, expected.at<cv::Vec3b>(y, x)[2]), 1e-6);
}

TEST(ModelManifest, NetworkInputRejectsUnusableImages) {
  const ModelManifest m = image_manifest(3, 2, ResizePolicy::kExact, false);
  std::vector<float> chw(18);
  ImageFrame empty;
  empty.source = "empty.png";
  EXPECT_THROW(image_to_network_input(empty, m, chw.data()), Error);
  ImageFrame gray;
  gray.rgb = cv::Mat(2, 3, CV_8UC1, cv::Scalar(7));
  EXPECT_THROW(image_to_network_input(gray, m, chw.data()), Error);
  ImageFrame wrong_size;
  wrong_size.rgb = test_image(4, 2);
  wrong_size.source = "big.png";
  try {
    image_to_network_input(wrong_size, m, chw.data());
    ADD_FAILURE() << "wrong size accepted under the exact policy";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("big.png"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {
// Found by fuzz_model_manifest: a number JSON cannot hold escaped as nlohmann's out_of_range.
TEST(ModelManifestFuzzRegression, OutOfRangeNumbersAreErrorsNamingTheFile) {
  try {
    parse_model_manifest("777E7777", "m.json");
    FAIL() << "accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("m.json"), std::string::npos) << e.what();
  }
}
}  // namespace
}  // namespace slamvdb
