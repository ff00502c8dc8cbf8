// The per-image baseline on a short SIMULATED sequence (synth + the simulated encoders).
#include "slamvdb/eval/image_baseline.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/eval/label_images.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/error_of.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;

class ImageBaselineTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("slamvdb_image_baseline_test_" + std::to_string(::getpid()));
    synth::SynthConfig config;
    config.seed = 5;
    config.length_m = 12.0;
    config.image_width = 192;
    config.image_height = 120;
    synth::write_synthetic_sequence(config, dir_, true);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static SimulatedEncoderConfig encoder() {
    SimulatedEncoderConfig c = SimulatedEncoderConfig::clean();  // the near-perfect one, by name
    c.dim = 32;
    c.width = 96;
    c.height = 60;
    return c;
  }
  static EncoderFeatureSource source() {
    return EncoderFeatureSource(std::make_unique<SimulatedDenseEncoder>(encoder()), EncoderFeatureSource::Input::kLabels);
  }
  // The coarse classes' simulated text embeddings as queries.
  static QuerySet text_queries(const Ontology& o) {
    SimulatedTextEncoder text(encoder());
    QueryMatrix v(o.num_classes(), text.dim());
    for (int k = 0; k < o.num_classes(); ++k)
      v.row(k) = Eigen::Map<const Eigen::RowVectorXf>(text.encode(o.classes()[k].name).data(), text.dim());
    return make_query_set(o, v, text.model_id());
  }

  static fs::path dir_;
};
fs::path ImageBaselineTest::dir_;

TEST_F(ImageBaselineTest, ScoresEveryLabelledPixelWithTheMapsRule) {
  const Sequence seq = read_sequence(dir_);
  ASSERT_GE(seq.images.size(), 5u);
  const Ontology o = Ontology::builtin("rellis3d-coarse");
  const QuerySet q = text_queries(o);
  auto features = source();
  std::size_t calls = 0;
  const ImageBaselineResult r =
      evaluate_image_baseline(seq.images, features, q, o, {}, [&](std::size_t done, std::size_t total) {
        EXPECT_EQ(done, ++calls);
        EXPECT_EQ(total, seq.images.size());
      });
  EXPECT_EQ(r.images, seq.images.size());
  EXPECT_EQ(r.without_labels, 0u);
  EXPECT_EQ(r.pixels, seq.images.size() * 96 * 60);  // RELLIS-3D labels: no unlabelled ids
  EXPECT_EQ(r.pixels, r.matrix.scored() + r.matrix.ignored());
  EXPECT_GT(r.matrix.ignored(), 0u);  // sky is void: never scored
  const double accuracy = *r.matrix.accuracy();
  EXPECT_GT(accuracy, 0.6);   // the simulated features are mostly right...
  EXPECT_LT(accuracy, 0.99);  // ...but not perfect (blob confusions, noise, blur)
  EXPECT_EQ(r.matrix.recalled(*o.find_class("void")), 0u);  // void never wins

  // The rule off: void can win, and the accuracy can only drop.
  auto features2 = source();
  const ImageBaselineResult plain =
      evaluate_image_baseline(seq.images, features2, q, o, {.classify = {.void_to_second_best = false}});
  EXPECT_EQ(plain.matrix.scored(), r.matrix.scored());
  EXPECT_LE(*plain.matrix.accuracy(), accuracy);

  // One image by hand: the same counts.
  auto features3 = source();
  const ImageBaselineResult one = evaluate_image_baseline(std::span(seq.images).first(1), features3, q, o);
  const FeatureMap map = source().features_for(seq.images[0]);
  const auto labels = read_labels_at(seq.images[0].labels, map.width(), map.height());
  const QueryClassifier classifier(q);
  uint64_t correct = 0, scored = 0;
  for (int i = 0; i < map.width() * map.height(); ++i) {
    const int truth = o.ground_truth()(labels[i]);
    if (o.is_void(truth)) continue;
    ++scored;
    correct += classifier.classify(map.values().subspan(std::size_t(i) * map.dim(), map.dim()))[0].class_index == truth;
  }
  EXPECT_EQ(one.matrix.scored(), scored);
  EXPECT_DOUBLE_EQ(*one.matrix.accuracy(), double(correct) / double(scored));
}

TEST_F(ImageBaselineTest, RefusesForeignQueriesAndCountsImagesWithoutLabels) {
  Sequence seq = read_sequence(dir_);
  const Ontology o = Ontology::builtin("rellis3d-coarse");
  QuerySet q = text_queries(o);
  auto features = source();
  q.model_id = "clip-vit-b32";
  EXPECT_NE(testing::error_of([&] { evaluate_image_baseline(seq.images, features, q, o); }).find("belong to model 'clip-vit-b32'"),
            std::string::npos);
  ImageBaselineOptions override;
  override.model_check = ModelIdCheck::kIgnore;
  EXPECT_EQ(testing::error_of([&] { evaluate_image_baseline(std::span(seq.images).first(1), features, q, o, override); }),
            "");
  EXPECT_NE(testing::error_of([&] { evaluate_image_baseline(seq.images, features, text_queries(o), Ontology::builtin("rellis3d-fine")); })
                .find("are no class of ontology 'rellis3d-fine'"),
            std::string::npos);

  std::vector<ImageRecord> images(seq.images.begin(), seq.images.begin() + 3);
  images[1].labels.clear();
  const ImageBaselineResult r = evaluate_image_baseline(images, features, text_queries(o), o);
  EXPECT_EQ(r.images, 2u);
  EXPECT_EQ(r.without_labels, 1u);
  images[2].labels = dir_ / "missing.png";
  EXPECT_NE(testing::error_of([&] { evaluate_image_baseline(images, features, text_queries(o), o); }).find("missing.png"),
            std::string::npos);
}

// Label files are read like camera images: the header's size is checked before any pixel is
// decoded, so a small damaged file that claims a huge image is an Error naming it, never gigabytes.
TEST(LabelImages, AHugeOrDamagedLabelFileIsAnErrorNamingItBeforeDecoding) {
  const fs::path dir = fs::temp_directory_path() / ("slamvdb_label_images_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::vector<unsigned char> png;
  ASSERT_TRUE(cv::imencode(".png", cv::Mat(1, 1, CV_8UC1, cv::Scalar(3)), png));
  const fs::path small = dir / "small.png";
  std::ofstream(small, std::ios::binary).write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
  EXPECT_EQ(read_labels_at(small, 2, 2), std::vector<uint16_t>(4, 3));

  // IHDR's width and height (bytes 16-23, big-endian) say 20000 x 20000 = 400 megapixels.
  for (int i : {16, 20}) {
    png[i] = 0, png[i + 1] = 0, png[i + 2] = 0x4e, png[i + 3] = 0x20;
  }
  const fs::path huge = dir / "huge.png";
  std::ofstream(huge, std::ios::binary).write(reinterpret_cast<const char*>(png.data()), std::streamsize(png.size()));
  const std::string refused = testing::error_of([&] { read_labels_at(huge, 2, 2); });
  EXPECT_NE(refused.find("huge.png"), std::string::npos) << refused;
  EXPECT_NE(refused.find("refused before decoding"), std::string::npos) << refused;

  const fs::path text = dir / "labels.png";
  std::ofstream(text) << "not an image";
  const std::string damaged = testing::error_of([&] { read_labels_at(text, 2, 2); });
  EXPECT_NE(damaged.find("neither a PNG nor a JPEG"), std::string::npos) << damaged;
  EXPECT_NE(testing::error_of([&] { read_labels_at(dir / "missing.png", 2, 2); }).find("missing.png"),
            std::string::npos);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace slamvdb
