#include "slamvdb/inference/simulated_encoders.hpp"

#include <gtest/gtest.h>

#include <chrono>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/ontology.hpp"

namespace slamvdb {
namespace {

using RowMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

int row_of(std::string_view name) {
  const auto& classes = rellis_classes();
  for (std::size_t i = 0; i < classes.size(); ++i)
    if (classes[i].name == name) return static_cast<int>(i);
  ADD_FAILURE() << "no class " << name;
  return 0;
}

// An off-road scene in RELLIS-3D ids at a quarter of the camera resolution.
ImageFrame scene(double stamp) {
  cv::Mat labels(300, 480, CV_8UC1, cv::Scalar(3));                        // grass
  cv::rectangle(labels, {0, 0}, {479, 70}, cv::Scalar(7), cv::FILLED);     // sky
  cv::rectangle(labels, {0, 70}, {239, 130}, cv::Scalar(4), cv::FILLED);   // tree
  cv::rectangle(labels, {240, 70}, {479, 130}, cv::Scalar(19), cv::FILLED);  // bush
  cv::rectangle(labels, {180, 130}, {300, 299}, cv::Scalar(1), cv::FILLED);  // dirt trail
  cv::circle(labels, {240, 240}, 30, cv::Scalar(31), cv::FILLED);          // puddle
  cv::rectangle(labels, {20, 200}, {120, 280}, cv::Scalar(33), cv::FILLED);  // mud
  cv::rectangle(labels, {360, 200}, {470, 290}, cv::Scalar(10), cv::FILLED); // asphalt
  cv::rectangle(labels, {330, 140}, {350, 200}, cv::Scalar(17), cv::FILLED); // person
  cv::rectangle(labels, {100, 131}, {104, 190}, cv::Scalar(5), cv::FILLED);  // pole
  return ImageFrame{stamp, {}, labels, "scene.png"};
}

// Per pixel, the class whose prototype is closest.
std::vector<int> argmax_classes(const FeatureMap& f, const PrototypeMatrix& prototypes) {
  const Eigen::Map<const RowMatrix> features(f.values().data(), static_cast<Eigen::Index>(f.pixels()), f.dim());
  const RowMatrix scores = features * prototypes.transpose();
  std::vector<int> best(scores.rows());
  for (Eigen::Index i = 0; i < scores.rows(); ++i) scores.row(i).maxCoeff(&best[i]);
  return best;
}

double agreement(const std::vector<int>& classes, const cv::Mat& labels, const SimulatedEncoderConfig& config) {
  cv::Mat small;
  cv::resize(labels, small, cv::Size(config.width, config.height), 0, 0, cv::INTER_NEAREST);
  int same = 0;
  for (int i = 0; i < small.rows * small.cols; ++i) same += classes[i] == row_of(find_fine_class(small.data[i])->name);
  return static_cast<double>(same) / (small.rows * small.cols);
}

TEST(SimulatedEncoders, RelatedClassesHaveCorrelatedPrototypes) {
  const PrototypeMatrix p = simulated_class_prototypes({});
  const auto cosine = [&](std::string_view a, std::string_view b) { return p.row(row_of(a)).dot(p.row(row_of(b))); };
  const auto& classes = rellis_classes();
  float min_related = 1.f, max_unrelated = -1.f;
  for (std::size_t i = 0; i < classes.size(); ++i)
    for (std::size_t j = i + 1; j < classes.size(); ++j) {
      const float c = p.row(i).dot(p.row(j));
      if (classes[i].coarse == classes[j].coarse) min_related = std::min(min_related, c);
      else max_unrelated = std::max(max_unrelated, c);
    }
  EXPECT_GT(min_related, 0.35f);
  EXPECT_LT(max_unrelated, 0.25f);
  EXPECT_GT(cosine("grass", "dirt"), cosine("grass", "tree"));
  EXPECT_GT(cosine("mud", "rubble"), cosine("mud", "asphalt"));
  EXPECT_GT(cosine("mud", "puddle"), cosine("puddle", "sky"));
  for (Eigen::Index i = 0; i < p.rows(); ++i) EXPECT_NEAR(p.row(i).norm(), 1.f, 1e-5f);
}

// The clean encoder's per-view blob swaps average out over views (the realistic encoder's
// persistent errors do not, by design: honest_accuracy_test).
TEST(SimulatedEncoders, SingleViewIsMostlyRightButImperfectAndViewsAverageOut) {
  const SimulatedEncoderConfig config = SimulatedEncoderConfig::clean();  // 512 x 128 x 192
  SimulatedDenseEncoder encoder(config);
  const PrototypeMatrix prototypes = simulated_class_prototypes(config);
  const cv::Mat labels = scene(0.0).labels;

  FeatureMap sum(config.dim, config.height, config.width);
  double single = 0.0;
  constexpr int kViews = 20;
  for (int v = 0; v < kViews; ++v) {
    const FeatureMap f = encoder.encode(scene(100.0 + 0.1 * v));
    ASSERT_EQ(f.dim(), 512);
    ASSERT_EQ(f.height(), 128);
    ASSERT_EQ(f.width(), 192);
    if (v == 0) {
      single = agreement(argmax_classes(f, prototypes), labels, config);
      for (int y = 0; y < f.height(); y += 17)
        for (int x = 0; x < f.width(); x += 13)
          EXPECT_NEAR(Eigen::Map<const Eigen::VectorXf>(f.pixel(x, y), f.dim()).norm(), 1.f, 1e-4f);
    }
    for (std::size_t i = 0; i < sum.size(); ++i) sum.values()[i] += f.values()[i];
  }
  const double averaged = agreement(argmax_classes(sum, prototypes), labels, config);
  EXPECT_GT(single, 0.70);
  EXPECT_LT(single, 0.97);
  EXPECT_GT(averaged, 0.95);
  EXPECT_GT(averaged, single + 0.03);
}

TEST(SimulatedEncoders, DeterministicPerSeedAndStamp) {
  for (const char* preset : {"clean", "realistic"}) {
    SCOPED_TRACE(preset);
    SimulatedEncoderConfig config = simulated_encoder_preset(preset, {});
    config.dim = 32;
    config.height = 48;
    config.width = 64;
    SimulatedDenseEncoder a(config), b(config);
    const FeatureMap f1 = a.encode(scene(5.0)), f2 = b.encode(scene(5.0)), f3 = a.encode(scene(5.1));
    EXPECT_EQ(f1, f2);
    EXPECT_NE(f1, f3);
    config.seed = 2;
    EXPECT_NE(SimulatedDenseEncoder(config).encode(scene(5.0)), f1);
    EXPECT_NE(SimulatedDenseEncoder(config).model_id(), a.model_id());
  }
}

// SIMULATED half-precision output: the fp32 features rounded to fp16, nothing else; the model id
// stays (the same embedding space), and a reused fp32 buffer switches precision.
TEST(SimulatedEncoders, Fp16OutputIsTheFp32OutputRounded) {
  for (const char* preset : {"clean", "realistic"}) {
    SCOPED_TRACE(preset);
    SimulatedEncoderConfig config = simulated_encoder_preset(preset, {});
    config.dim = 37;
    config.height = 24;
    config.width = 32;
    SimulatedDenseEncoder fp32(config);
    config.output_precision = EmbeddingPrecision::kFloat16;
    SimulatedDenseEncoder fp16(config);
    EXPECT_EQ(fp16.model_id(), fp32.model_id());
    const FeatureMap wide = fp32.encode(scene(5.0));
    FeatureMap half = fp32.encode(scene(4.0));  // an fp32 buffer to reuse
    fp16.encode_into(scene(5.0), half);
    EXPECT_EQ(half.precision(), EmbeddingPrecision::kFloat16);
    EXPECT_EQ(half, wide.converted(EmbeddingPrecision::kFloat16));
  }
}

TEST(SimulatedEncoders, MissingOrWrongLabelsAreErrors) {
  SimulatedDenseEncoder encoder;
  ImageFrame no_labels{1.0, cv::Mat(10, 10, CV_8UC3, cv::Scalar(1, 2, 3)), {}, "rgb_only.png"};
  EXPECT_THROW(encoder.encode(no_labels), Error);
  ImageFrame wide{1.0, {}, cv::Mat(10, 10, CV_16UC1, cv::Scalar(3)), "wide.png"};
  EXPECT_THROW(encoder.encode(wide), Error);
  ImageFrame unknown = scene(1.0);
  unknown.labels.at<uint8_t>(5, 7) = 2;  // not a RELLIS-3D class
  try {
    encoder.encode(unknown);
    ADD_FAILURE() << "label 2 was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("label 2 at pixel (7, 5)"), std::string::npos) << e.what();
  }
  SimulatedEncoderConfig bad;
  bad.confusion_rate = 1.5f;
  EXPECT_THROW(SimulatedDenseEncoder{bad}, Error);
  bad = {};
  bad.dim = 0;
  EXPECT_THROW(SimulatedTextEncoder{bad}, Error);
}

TEST(SimulatedEncoders, TextEncoderReturnsTheDenseEncodersPrototypes) {
  SimulatedEncoderConfig config = SimulatedEncoderConfig::clean();  // the prototypes: no failure mode involved
  config.seed = 7;
  SimulatedTextEncoder text(config);
  const PrototypeMatrix p = simulated_class_prototypes(config);
  const auto vec = [](const std::vector<float>& v) { return Eigen::Map<const Eigen::VectorXf>(v.data(), v.size()); };
  for (const auto& c : rellis_classes()) {
    const std::vector<float> v = text.encode(c.name);
    ASSERT_EQ(v.size(), 512u);
    EXPECT_LT((vec(v) - p.row(row_of(c.name)).transpose()).norm(), 1e-6f) << c.name;
  }
  EXPECT_EQ(text.encode("tall grass"), text.encode("grass"));
  EXPECT_EQ(text.encode("A photo of two Trees."), text.encode("tree"));
  EXPECT_EQ(text.encode("bushes"), text.encode("bush"));
  const Eigen::VectorXf rough = (p.row(row_of("dirt")) + p.row(row_of("grass"))).transpose().normalized();
  EXPECT_LT((vec(text.encode("rough")) - rough).norm(), 1e-6f);
  const Eigen::VectorXf mud_puddle = (p.row(row_of("mud")) + p.row(row_of("puddle"))).transpose().normalized();
  EXPECT_LT((vec(text.encode("mud puddle")) - mud_puddle).norm(), 1e-6f);
  try {
    text.encode("a spaceship");
    ADD_FAILURE() << "unknown text was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("grass"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("obstacle"), std::string::npos) << e.what();
  }
  EXPECT_EQ(text.model_id(), SimulatedDenseEncoder(config).model_id());
  EXPECT_NE(text.model_id().find("simulated"), std::string::npos);
}

// The opt-in SIMULATED text-image gap: text embeddings lean towards other classes' image
// prototypes; the image side and the model id are unchanged.
TEST(SimulatedEncoders, TextGapMovesNamesTowardsOtherClasses) {
  SimulatedEncoderConfig config;
  config.text_gap = 3.f;
  SimulatedTextEncoder text(config);
  const PrototypeMatrix p = simulated_class_prototypes(config);
  int leaning = 0;
  for (const auto& c : rellis_classes()) {
    const std::vector<float> v = text.encode(c.name);
    const Eigen::VectorXf cos = p * Eigen::Map<const Eigen::VectorXf>(v.data(), v.size());
    EXPECT_LT(cos[row_of(c.name)], 0.9f) << c.name;
    Eigen::Index best;
    cos.maxCoeff(&best);
    leaning += best != row_of(c.name);
  }
  EXPECT_GE(leaning, 5);  // several names are closer to another class's pixels than to their own
  EXPECT_EQ(text.model_id(), SimulatedTextEncoder(SimulatedEncoderConfig{}).model_id());
  config.text_gap = -1.f;
  EXPECT_THROW(SimulatedTextEncoder{config}, Error);
}

TEST(SimulatedEncoders, OtherDimensionsWork) {
  SimulatedEncoderConfig config;
  config.dim = 64;
  config.height = 60;
  config.width = 80;
  config.confusion_cell = 8;
  SimulatedDenseEncoder dense(config);
  const FeatureMap f = dense.encode(scene(3.0));
  ASSERT_EQ(f.size(), 64u * 60 * 80);
  EXPECT_NEAR(Eigen::Map<const Eigen::VectorXf>(f.pixel(40, 30), 64).norm(), 1.f, 1e-4f);
  EXPECT_GT(agreement(argmax_classes(f, simulated_class_prototypes(config)), scene(0).labels, config), 0.6);
  EXPECT_EQ(SimulatedTextEncoder(config).encode("mud").size(), 64u);

  SimulatedImageEncoder image(config);
  const std::vector<float> e = image.encode(scene(3.0));
  ASSERT_EQ(e.size(), 64u);
  const Eigen::Map<const Eigen::VectorXf> v(e.data(), 64);
  EXPECT_NEAR(v.norm(), 1.f, 1e-5f);
  // The scene is mostly grass: its image embedding is closer to grass than to sky or person.
  const PrototypeMatrix p = simulated_class_prototypes(config);
  EXPECT_GT(v.dot(p.row(row_of("grass"))), v.dot(p.row(row_of("sky"))));
  EXPECT_GT(v.dot(p.row(row_of("grass"))), v.dot(p.row(row_of("person"))));
}

TEST(SimulatedEncoders, EncodesAFullSizeFrameQuickly) {
  SimulatedDenseEncoder encoder;
  const ImageFrame frame = scene(9.0);
  encoder.encode(frame);  // warm-up
  const auto start = std::chrono::steady_clock::now();
  constexpr int kFrames = 5;
  for (int i = 0; i < kFrames; ++i) encoder.encode(scene(9.0 + i));
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count() / kFrames;
  EXPECT_LT(ms, 400.0) << "target < 40 ms per frame on one idle core";  // loose: the suite shares 2 cores
}

}  // namespace
}  // namespace slamvdb
