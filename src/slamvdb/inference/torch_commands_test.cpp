// The CLI commands that run the TorchScript test networks: embed-text, segment, map --features model,
// train-queries.
#include "slamvdb/testing/torch_encoders_fixture.hpp"

namespace slamvdb::torch_test {
namespace {

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
}  // namespace slamvdb::torch_test
