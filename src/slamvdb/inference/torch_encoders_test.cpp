// The TorchScript backend against Python: tools/make_test_models.py builds small randomly
// initialised networks with the real ones' interfaces and computes reference outputs in Python
// (pre-processing included); the C++ encoders must reproduce them. Also every failure mode.
#include "slamvdb/inference/torch_encoders.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/testing/shared_data.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/text_file.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

const fs::path kTools = fs::path(SLAMVDB_SOURCE_DIR) / "tools";

// The interpreter CMake found (Debian's, with python3-torch), unless $SLAMVDB_PYTHON names
// another; empty if it cannot import torch and numpy.
std::string torch_python() {
  const char* env = std::getenv("SLAMVDB_PYTHON");
  const std::string python = env ? env : SLAMVDB_PYTHON;
  return std::system((python + " -c 'import torch, numpy' >/dev/null 2>&1").c_str()) == 0 ? python : std::string();
}

using testing::quote_path;
using testing::read_text_file;

// A 3 x H x W float array of 0..255 values (as make_test_models.py saves images) as RGB cv::Mat.
cv::Mat read_image_npy(const fs::path& p) {
  const FeatureMap planar = read_feature_npy(p);
  cv::Mat rgb(planar.height(), planar.width(), CV_8UC3);
  for (int y = 0; y < planar.height(); ++y)
    for (int x = 0; x < planar.width(); ++x)
      for (int c = 0; c < 3; ++c) rgb.at<cv::Vec3b>(y, x)[c] = static_cast<uint8_t>(planar.pixel(x, y)[c]);
  return rgb;
}

ImageFrame frame_of(cv::Mat rgb, std::string source) {
  ImageFrame f;
  f.rgb = std::move(rgb);
  f.source = std::move(source);
  return f;
}

float max_abs_diff(const float* a, const float* b, std::size_t n) {
  float worst = 0.0f;
  for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  return worst;
}

// `fn()` must throw Error whose message contains every needle.
template <typename Fn>
void expect_error(Fn&& fn, std::initializer_list<std::string> needles) {
  try {
    fn();
    ADD_FAILURE() << "no Error thrown";
  } catch (const Error& e) {
    const std::string what = e.what();
    for (const auto& n : needles) EXPECT_NE(what.find(n), std::string::npos) << "'" << n << "' not in: " << what;
  }
}

class TorchEncoders : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    python_ = torch_python();
    if (python_.empty()) return;
    dir_ = fs::temp_directory_path() / ("slamvdb_torch_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    const std::string cmd = python_ + " " + quote_path(kTools / "make_test_models.py") + " --out " + quote_path(dir_) +
                            " --vocab " + quote_path(testing::kClipVocab) + " > " + quote_path(dir_ / "make.log") + " 2>&1";
    models_ok_ = std::system(cmd.c_str()) == 0;
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (python_.empty()) GTEST_SKIP() << "no python3 with torch and numpy (set SLAMVDB_PYTHON)";
    ASSERT_TRUE(models_ok_) << "tools/make_test_models.py failed:\n" << read_text_file(dir_ / "make.log");
  }

  static fs::path model(const std::string& name) { return dir_ / (name + ".pt"); }

  // NAME.pt beside a copy of BASE.json changed by `edit`: the same network, another manifest.
  template <typename Edit>
  static fs::path variant(const std::string& base, const std::string& name, Edit&& edit) {
    json manifest = json::parse(read_text_file(dir_ / (base + ".json")));
    edit(manifest);
    std::ofstream(dir_ / (name + ".json")) << manifest.dump(2);
    fs::remove(dir_ / (name + ".pt"));
    fs::create_symlink(dir_ / (base + ".pt"), dir_ / (name + ".pt"));
    return dir_ / (name + ".pt");
  }

  static int run_cli(const std::string& args, const fs::path& stdout_file) {
    return std::system((std::string(SLAMVDB_CLI_PATH) + " " + args + " > " + quote_path(stdout_file) + " 2>&1").c_str());
  }

  static inline std::string python_;
  static inline fs::path dir_;
  static inline bool models_ok_ = false;
};

TEST_F(TorchEncoders, DenseEncoderReproducesPythonIncludingPreprocessing) {
  TorchDenseImageEncoder encoder(model("dense"));
  EXPECT_EQ(encoder.model_id(), "tiny-lseg-random-init");
  EXPECT_EQ(encoder.dim(), 16);
  const FeatureMap expected = read_feature_npy(dir_ / "dense_output.npy");
  const FeatureMap got = encoder.encode(frame_of(read_image_npy(dir_ / "dense_input.npy"), "dense_input"));
  ASSERT_EQ(got.dim(), expected.dim());
  ASSERT_EQ(got.height(), 32);
  ASSERT_EQ(got.width(), 48);
  ASSERT_EQ(got.height(), expected.height());
  ASSERT_EQ(got.width(), expected.width());
  EXPECT_LT(max_abs_diff(got.values().data(), expected.values().data(), got.size()), 1e-5f);
  float norm2 = 0.0f;
  for (int c = 0; c < got.dim(); ++c) norm2 += got.pixel(5, 7)[c] * got.pixel(5, 7)[c];
  EXPECT_NEAR(norm2, 1.0f, 1e-5f);
  // The comparison is sensitive to pre-processing: swapping the channel order breaks it.
  TorchDenseImageEncoder bgr(variant("dense", "dense_bgr", [](json& m) { m["input"]["channel_order"] = "BGR"; }));
  const FeatureMap swapped = bgr.encode(frame_of(read_image_npy(dir_ / "dense_input.npy"), "dense_input"));
  EXPECT_GT(max_abs_diff(swapped.values().data(), expected.values().data(), got.size()), 1e-3f);
}

TEST_F(TorchEncoders, DenseBatchesEqualSingleFrames) {
  const fs::path batched = variant("dense", "dense_batch2", [](json& m) { m["runtime"]["batch_size"] = 2; });
  TorchDenseImageEncoder encoder(batched);
  const cv::Mat a = read_image_npy(dir_ / "dense_input.npy");
  cv::Mat b, c;
  cv::flip(a, b, 1);
  cv::flip(a, c, 0);
  const std::vector<ImageFrame> frames{frame_of(a, "a"), frame_of(b, "b"), frame_of(c, "c")};  // batches 2 + 1
  const std::vector<FeatureMap> maps = encoder.encode_batch(frames);
  ASSERT_EQ(maps.size(), 3u);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    const FeatureMap single = encoder.encode(frames[i]);
    ASSERT_EQ(single.size(), maps[i].size());
    EXPECT_LT(max_abs_diff(single.values().data(), maps[i].values().data(), single.size()), 1e-5f) << i;
  }
  EXPECT_GT(max_abs_diff(maps[0].values().data(), maps[1].values().data(), maps[0].size()), 1e-2f);
  EXPECT_TRUE(encoder.encode_batch({}).empty());
}

TEST_F(TorchEncoders, ImageEncoderReproducesPythonIncludingCentreCrop) {
  TorchImageEncoder encoder(model("image"));
  const FeatureMap expected = read_feature_npy(dir_ / "image_output.npy");  // dim x 1 x 1
  const cv::Mat image = read_image_npy(dir_ / "image_input.npy");
  ASSERT_EQ(image.cols, 40);  // the 32 x 32 model sees the centre columns 4..35
  const std::vector<float> got = encoder.encode(frame_of(image, "image_input"));
  ASSERT_EQ(got.size(), static_cast<std::size_t>(expected.dim()));
  EXPECT_LT(max_abs_diff(got.data(), expected.values().data(), got.size()), 1e-5f);
}

TEST_F(TorchEncoders, TextEncoderReproducesPythonIncludingTokenizer) {
  TorchTextEncoder encoder(model("text"));
  const FeatureMap expected = read_feature_npy(dir_ / "text_output.npy");  // dim x 1 x prompts
  std::istringstream prompts(read_text_file(dir_ / "text_prompts.txt"));
  std::string prompt;
  int i = 0;
  for (; std::getline(prompts, prompt); ++i) {
    ASSERT_LT(i, expected.width());
    const std::vector<float> got = encoder.encode(prompt);
    ASSERT_EQ(got.size(), static_cast<std::size_t>(expected.dim()));
    EXPECT_LT(max_abs_diff(got.data(), expected.pixel(i, 0), got.size()), 1e-5f) << "prompt: " << prompt;
  }
  EXPECT_EQ(i, expected.width());
  const std::vector<float> a = encoder.encode("tall grass"), b = encoder.encode("asphalt");
  EXPECT_GT(max_abs_diff(a.data(), b.data(), a.size()), 1e-3f);
}

TEST_F(TorchEncoders, ExportScriptsProduceLoadableModels) {
  const fs::path out = dir_ / "exported";
  for (const char* script : {"export_lseg.py", "export_clip.py"}) {
    const std::string cmd = python_ + " " + quote_path(kTools / script) + " --random-init-test --out " + quote_path(out) +
                            " --vocab " + quote_path(testing::kClipVocab) + " > " + quote_path(dir_ / "export.log") + " 2>&1";
    ASSERT_EQ(std::system(cmd.c_str()), 0) << script << ":\n" << read_text_file(dir_ / "export.log");
  }
  // Tiny networks: one thread (the scripts leave the count to libtorch). Warm-up checks shapes and norms.
  const TorchEncoderOptions one_thread{.threads = 1};
  TorchDenseImageEncoder lseg(out / "lseg_dense.pt", one_thread);
  TorchTextEncoder lseg_text(out / "lseg_text.pt", one_thread);
  EXPECT_EQ(lseg.dim(), lseg_text.dim());
  EXPECT_EQ(lseg.manifest().output.height * 2, lseg.manifest().input.height);
  EXPECT_EQ(lseg.manifest().input.mean[0], 0.5f);
  TorchImageEncoder clip_image(out / "clip_image.pt", one_thread);
  TorchTextEncoder clip_text(out / "clip_text.pt", one_thread);
  EXPECT_EQ(clip_image.dim(), clip_text.dim());
  EXPECT_EQ(clip_image.manifest().input.resize, ResizePolicy::kResizeShortCenterCrop);
  // Any image size goes in: the manifests ask for resizing.
  const cv::Mat big(300, 500, CV_8UC3, cv::Scalar(10, 200, 30));
  EXPECT_EQ(lseg.encode(frame_of(big, "big")).height(), lseg.manifest().output.height);
  EXPECT_EQ(clip_image.encode(frame_of(big, "big")).size(), static_cast<std::size_t>(clip_image.dim()));
}

TEST_F(TorchEncoders, MissingOrUnreadableFilesAreReported) {
  fs::copy_file(dir_ / "dense.json", dir_ / "no_model.json", fs::copy_options::overwrite_existing);
  expect_error([&] { TorchDenseImageEncoder e(dir_ / "no_model.pt"); }, {"no_model.pt", "does not exist"});
  fs::copy_file(model("dense"), dir_ / "no_manifest.pt", fs::copy_options::overwrite_existing);
  expect_error([&] { TorchDenseImageEncoder e(dir_ / "no_manifest.pt"); }, {"no_manifest.json", "not found"});
  fs::copy_file(dir_ / "dense.json", dir_ / "corrupt.json", fs::copy_options::overwrite_existing);
  std::ofstream(dir_ / "corrupt.pt") << "this is not a TorchScript archive";
  expect_error([&] { TorchDenseImageEncoder e(dir_ / "corrupt.pt"); }, {"cannot load TorchScript model", "corrupt.pt"});
  expect_error([&] { TorchTextEncoder e(model("dense")); }, {"describes a dense_image model", "text encoder"});
  const fs::path no_vocab = variant("text", "no_vocab", [](json& m) { m["text"]["vocab"] = "missing_vocab.txt.gz"; });
  expect_error([&] { TorchTextEncoder e(no_vocab); }, {"missing_vocab.txt.gz", "does not exist"});
}

TEST_F(TorchEncoders, ManifestThatDoesNotMatchTheNetworkIsCaught) {
  const fs::path wrong_dim = variant("dense", "wrong_dim", [](json& m) { m["output"]["dim"] = 32; });
  expect_error([&] { TorchDenseImageEncoder e(wrong_dim); }, {"[1, 16, 32, 48]", "[1, 32, 32, 48]", "wrong_dim.json"});
  // Without warm-up the same mismatch surfaces on the first frame.
  TorchDenseImageEncoder lazy(wrong_dim, {.threads = 1, .warm_up = false});
  const cv::Mat image = read_image_npy(dir_ / "dense_input.npy");
  expect_error([&] { lazy.encode(frame_of(image, "frame_7.png")); }, {"frame_7.png", "[1, 32, 32, 48]"});

  const fs::path wrong_size = variant("image", "wrong_size", [](json& m) { m["output"]["dim"] = 8; });
  expect_error([&] { TorchImageEncoder e(wrong_size); }, {"[1, 16]", "[1, 8]"});
  const fs::path text_dim = variant("text", "text_dim", [](json& m) { m["output"]["dim"] = 512; });
  expect_error([&] { TorchTextEncoder e(text_dim); }, {"[1, 16]", "[1, 512]"});
  // The image model does not normalise; a manifest claiming it does is caught.
  const fs::path not_unit = variant("image", "not_unit", [](json& m) {
    m["output"]["l2_normalized"] = true;
    m["output"]["normalize_output"] = false;
  });
  expect_error([&] { TorchImageEncoder e(not_unit); }, {"l2_normalized", "not_unit.json"});
}

TEST_F(TorchEncoders, WrongImageSizeUnderExactPolicyIsReported) {
  const fs::path exact = variant("dense", "exact", [](json& m) { m["input"]["resize"] = "exact"; });
  TorchDenseImageEncoder encoder(exact);
  const cv::Mat wrong(40, 50, CV_8UC3, cv::Scalar::all(0));
  expect_error([&] { encoder.encode(frame_of(wrong, "cam_0042.jpg")); }, {"cam_0042.jpg", "50 x 40", "96 x 64"});
  EXPECT_EQ(encoder.encode(frame_of(read_image_npy(dir_ / "dense_input.npy"), "ok")).width(), 48);
}

TEST_F(TorchEncoders, NetworkThatThrowsIsReportedWithItsMessage) {
  expect_error([&] { TorchDenseImageEncoder e(model("throwing")); },
               {"deliberately-throwing", "warm-up image", "deliberate failure inside the model"});
}

TEST_F(TorchEncoders, EmbedTextCommandPrintsAndSavesTheEncodersVector) {
  TorchTextEncoder encoder(model("text"));
  const std::vector<float> expected = encoder.encode("tall grass");
  const fs::path out = dir_ / "embed.txt", npy = dir_ / "grass.npy";
  ASSERT_EQ(run_cli("embed-text 'tall grass' --model " + quote_path(model("text")) + " --json", out), 0) << read_text_file(out);
  const json j = json::parse(read_text_file(out));
  EXPECT_EQ(j["model_id"], "tiny-clip-text-random-init");
  EXPECT_EQ(j["text"], "tall grass");
  const auto v = j["embedding"].get<std::vector<float>>();
  ASSERT_EQ(v.size(), expected.size());
  EXPECT_LT(max_abs_diff(v.data(), expected.data(), v.size()), 1e-6f);

  ASSERT_EQ(run_cli("embed-text 'tall grass' --model " + quote_path(model("text")) + " --out " + quote_path(npy), out), 0)
      << read_text_file(out);
  // A .npy ends with the raw little-endian float32 data.
  std::ifstream in(npy, std::ios::binary);
  std::vector<float> saved(expected.size());
  in.seekg(-static_cast<std::streamoff>(saved.size() * sizeof(float)), std::ios::end);
  in.read(reinterpret_cast<char*>(saved.data()), static_cast<std::streamsize>(saved.size() * sizeof(float)));
  ASSERT_TRUE(in);
  EXPECT_EQ(saved, expected);
  EXPECT_NE(run_cli("embed-text grass --model " + quote_path(dir_ / "absent.pt"), out), 0);
  EXPECT_NE(read_text_file(out).find("absent.json"), std::string::npos) << read_text_file(out);
}

TEST_F(TorchEncoders, SegmentCommandWritesFeaturesAndBestClassImage) {
  const fs::path image = dir_ / "scene.png", out_dir = dir_ / "segment", log = dir_ / "segment.log";
  cv::Mat rgb = read_image_npy(dir_ / "dense_input.npy"), bgr;
  cv::resize(rgb, rgb, {192, 128}, 0, 0, cv::INTER_NEAREST);  // the encoder resizes back to 96 x 64
  cv::cvtColor(rgb, bgr, cv::COLOR_RGB2BGR);
  ASSERT_TRUE(cv::imwrite(image.string(), bgr));
  ASSERT_EQ(run_cli("segment " + quote_path(image) + " --model " + quote_path(model("dense")) + " --text-model " +
                        quote_path(model("text")) + " --classes 'grass, tree,sky' --out-dir " + quote_path(out_dir),
                    log),
            0)
      << read_text_file(log);

  TorchDenseImageEncoder dense(model("dense"));
  const FeatureMap expected = dense.encode(frame_of(rgb, "scene.png"));
  const FeatureMap features = read_feature_npy(out_dir / "features.npy");
  ASSERT_EQ(features.size(), expected.size());
  EXPECT_LT(max_abs_diff(features.values().data(), expected.values().data(), expected.size()), 1e-5f);

  // The best class per pixel, recomputed here from the same encoders.
  TorchTextEncoder text(model("text"));
  std::vector<std::vector<float>> classes;
  for (const char* name : {"grass", "tree", "sky"}) classes.push_back(text.encode(name));
  const cv::Mat labels = cv::imread((out_dir / "labels.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(labels.type(), CV_8UC1);
  ASSERT_EQ(labels.size(), cv::Size(48, 32));
  for (int y = 0; y < 32; y += 5)
    for (int x = 0; x < 48; x += 7) {
      int best = 0;
      float best_score = -1e30f;
      for (int k = 0; k < 3; ++k) {
        float s = 0.0f;
        for (int c = 0; c < features.dim(); ++c) s += features.pixel(x, y)[c] * classes[k][c];
        if (s > best_score) best_score = s, best = k;
      }
      EXPECT_EQ(labels.at<uint8_t>(y, x), best) << x << "," << y;
    }
  const cv::Mat colour = cv::imread((out_dir / "classes.png").string(), cv::IMREAD_COLOR);
  EXPECT_EQ(colour.size(), cv::Size(48, 32));
  const std::string legend = read_text_file(out_dir / "legend.txt");
  EXPECT_NE(legend.find("0\tgrass\t#"), std::string::npos) << legend;
  EXPECT_NE(legend.find("1\ttree\t#"), std::string::npos) << legend;
  EXPECT_NE(legend.find("2\tsky\t#"), std::string::npos) << legend;
}

TEST_F(TorchEncoders, SegmentCommandRunsTheSimulatedEncodersOnGroundTruthLabels) {
  const fs::path fixture = testing::shared_dir() / "fixtures" / "rellis3d-000104";
  const fs::path image = fixture / "frame000104-1581624663_149.jpg",
                 labels = fixture / "frame000104-1581624663_149.png";
  if (!fs::exists(image) || !fs::exists(labels)) GTEST_SKIP() << "RELLIS-3D fixture not found at " << fixture;
  const fs::path out_dir = dir_ / "segment_simulated", log = dir_ / "segment_simulated.log";
  ASSERT_EQ(run_cli("segment " + quote_path(image) + " --simulated --labels " + quote_path(labels) +
                        " --classes grass,tree,bush,sky --out-dir " + quote_path(out_dir),
                    log),
            0)
      << read_text_file(log);
  const cv::Mat predicted = cv::imread((out_dir / "labels.png").string(), cv::IMREAD_UNCHANGED);
  ASSERT_EQ(predicted.size(), cv::Size(192, 128));
  cv::Mat truth = cv::imread(labels.string(), cv::IMREAD_UNCHANGED);
  cv::resize(truth, truth, predicted.size(), 0, 0, cv::INTER_NEAREST);
  const std::map<int, int> index_of{{3, 0}, {4, 1}, {19, 2}, {7, 3}};  // RELLIS ids of the four classes
  int named = 0, agree = 0;
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      const auto it = index_of.find(truth.at<uint8_t>(y, x));
      if (it == index_of.end()) continue;
      ++named;
      agree += predicted.at<uint8_t>(y, x) == it->second;
    }
  ASSERT_GT(named, 1000);
  EXPECT_GT(static_cast<double>(agree) / named, 0.5) << agree << " of " << named;
  EXPECT_NE(read_text_file(log).find("simulated"), std::string::npos) << read_text_file(log);
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

// `slamvdb map --features model` runs the network on every image of a (simulated) sequence and
// fuses its features: the map's model id is the network's and its embeddings are 16-d.
TEST_F(TorchEncoders, MapCommandFusesTheNetworksFeatures) {
  const fs::path seq = dir_ / "seq", map = dir_ / "net.svdb";
  ASSERT_EQ(run_cli("synth " + quote_path(seq) + " --length 15 --image-size 192x120", dir_ / "synth.txt"), 0)
      << read_text_file(dir_ / "synth.txt");
  ASSERT_EQ(run_cli("map " + quote_path(seq) + " -o " + quote_path(map) + " --features model --model " +
                        quote_path(model("dense")) + " --dim 16",
                    dir_ / "map.txt"),
            0)
      << read_text_file(dir_ / "map.txt");
  const std::string out = read_text_file(dir_ / "map.txt");
  EXPECT_NE(out.find("network tiny-lseg-random-init: 16-d"), std::string::npos) << out;
  EXPECT_NE(out.find("0 failed"), std::string::npos) << out;
  ASSERT_EQ(run_cli("info " + quote_path(map), dir_ / "info.txt"), 0);
  const std::string info = read_text_file(dir_ / "info.txt");
  EXPECT_NE(info.find("tiny-lseg-random-init"), std::string::npos) << info;
  EXPECT_EQ(info.find(" 0 semantic voxels"), std::string::npos) << info;
  // A map dimension that does not match the network is refused with a clear message.
  EXPECT_NE(run_cli("map " + quote_path(seq) + " -o " + quote_path(dir_ / "bad.svdb") + " --features model --model " +
                        quote_path(model("dense")),
                    dir_ / "bad.txt"),
            0);
  EXPECT_NE(read_text_file(dir_ / "bad.txt").find("16 channels"), std::string::npos) << read_text_file(dir_ / "bad.txt");
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

// `slamvdb train-queries --features model --text-model`: features from the dense network on the
// RGB images, initial queries from the text network, both 16-d test networks (random weights,
// so only the plumbing is checked, not the accuracy).
TEST_F(TorchEncoders, TrainQueriesCommandRunsBothNetworks) {
  const fs::path seq = dir_ / "train_seq", queries = dir_ / "queries.json";
  ASSERT_EQ(run_cli("synth " + quote_path(seq) + " --length 8 --image-size 192x120", dir_ / "synth2.txt"), 0)
      << read_text_file(dir_ / "synth2.txt");
  ASSERT_EQ(run_cli("train-queries " + quote_path(seq) + " -o " + quote_path(queries) + " --features model --model " +
                        quote_path(model("dense")) + " --text-model " + quote_path(model("text")) +
                        " --epochs 1 --pixels-per-image 64 --val-fraction 0.3",
                    dir_ / "train.txt"),
            0)
      << read_text_file(dir_ / "train.txt");
  const std::string out = read_text_file(dir_ / "train.txt");
  EXPECT_NE(out.find("epoch 1/1: train loss"), std::string::npos) << out;
  EXPECT_NE(out.find("initialised from the text embeddings of the class names"), std::string::npos) << out;
  const json q = json::parse(read_text_file(queries));
  EXPECT_EQ(q["model_id"], "tiny-lseg-random-init");
  EXPECT_EQ(q["dim"], 16);
  EXPECT_EQ(q["classes"].size(), 6u);
}

}  // namespace
}  // namespace slamvdb
