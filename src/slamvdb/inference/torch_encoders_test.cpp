// The TorchScript backend against Python: the C++ encoders must reproduce the reference outputs that
// tools/make_test_models.py computes in Python (pre-processing included). Also every failure mode.
#include "slamvdb/testing/torch_encoders_fixture.hpp"

namespace slamvdb::torch_test {
namespace {

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
}  // namespace
}  // namespace slamvdb::torch_test
