// Query training end to end on a short SIMULATED sequence (synth + the simulated encoders), and
// the train-queries / eval-images / import-queries commands.
#include "slamvdb/training/train_queries.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstring>
#include <fstream>

#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::error_of;

class TrainQueriesTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / fmt::format("slamvdb_train_queries_test_{}", ::getpid());
    synth::SynthConfig config;
    config.seed = 3;
    config.length_m = 30.0;
    config.image_width = 192;
    config.image_height = 120;
    synth::write_synthetic_sequence(config, dir_, true);
    sequence_ = new Sequence(read_sequence(dir_));
  }
  static void TearDownTestSuite() {
    delete sequence_;
    fs::remove_all(dir_);
  }

  static SimulatedEncoderConfig encoder(float text_gap = 0.f) {
    SimulatedEncoderConfig c = SimulatedEncoderConfig::clean();  // the near-perfect one, by name
    c.dim = 64;
    c.width = 96;
    c.height = 60;
    c.text_gap = text_gap;
    return c;
  }
  static EncoderFeatureSource features() {
    return EncoderFeatureSource(std::make_unique<SimulatedDenseEncoder>(encoder()), EncoderFeatureSource::Input::kLabels);
  }
  static TrainQueriesOptions options() {
    TrainQueriesOptions o;
    o.pixels_per_image = 512;
    o.val_fraction = 0.25;
    o.trainer.epochs = 3;
    o.trainer.batch_size = 1024;
    return o;
  }

  static fs::path dir_;
  static Sequence* sequence_;
};
fs::path TrainQueriesTest::dir_;
Sequence* TrainQueriesTest::sequence_ = nullptr;

// The paper's case: text embeddings that do not match the image features well (here the
// SIMULATED text-image gap) classify badly; the trained queries separate the classes.
TEST_F(TrainQueriesTest, TrainingSeparatesTheClassesTheTextQueriesConfuse) {
  const Ontology o = Ontology::builtin("rellis3d-coarse");
  SimulatedTextEncoder text(encoder(3.f));
  auto source = features();
  TrainQueriesReport report;
  std::vector<EpochReport> seen;
  std::size_t images_done = 0;
  TrainingCallbacks callbacks;
  callbacks.image_progress = [&](std::size_t done, std::size_t) { images_done = done; };
  callbacks.epoch_done = [&](const EpochReport& r) { seen.push_back(r); };
  const QuerySet q = train_queries(sequence_->images, source, o, &text, options(), report, callbacks);

  ASSERT_EQ(report.epochs.size(), 4u);  // initial + 3
  ASSERT_EQ(seen.size(), 4u);
  EXPECT_EQ(images_done, sequence_->images.size());
  EXPECT_EQ(report.train_images + report.val_images, sequence_->images.size());
  EXPECT_EQ(report.val_images, static_cast<std::size_t>(std::lround(0.25 * sequence_->images.size())));
  EXPECT_EQ(report.train_pixels, report.train_images * 512);
  const EpochReport& init = report.epochs.front();
  const EpochReport& last = report.epochs.back();
  EXPECT_LT(*init.val_accuracy, 0.75);
  EXPECT_GT(*last.val_accuracy, 0.85);
  EXPECT_GT(*last.val_accuracy, *init.val_accuracy + 0.2);
  EXPECT_LT(*last.val_loss, 0.5 * *init.val_loss);
  EXPECT_LT(*last.train_loss, *report.epochs[1].train_loss);

  EXPECT_EQ(q.model_id, source.model_id());
  EXPECT_EQ(q.names, o.class_names());
  EXPECT_EQ(q.void_classes, o.void_classes());
  EXPECT_EQ(q.provenance.method, "train-queries");
  EXPECT_EQ(q.provenance.epochs, 3);
  EXPECT_EQ(q.provenance.accuracy, last.val_accuracy);
  EXPECT_NE(q.provenance.notes.at("init").find("text"), std::string::npos);
}

// With an ideal text encoder (no gap) the text queries are already near the simulation's ceiling
// (its confusions cannot be learnt away); training must not make them worse.
TEST_F(TrainQueriesTest, IdealTextQueriesStayAsGoodAndClassMeansNeedNoText) {
  const Ontology o = Ontology::builtin("rellis3d-coarse");
  SimulatedTextEncoder text(encoder());
  auto source = features();
  TrainQueriesReport with_text, with_means;
  train_queries(sequence_->images, source, o, &text, options(), with_text);
  EXPECT_GT(*with_text.epochs.front().val_accuracy, 0.85);
  EXPECT_GT(*with_text.epochs.back().val_accuracy, *with_text.epochs.front().val_accuracy - 0.01);

  TrainQueriesOptions mean = options();
  mean.init = QueryInit::kClassMean;
  mean.trainer.epochs = 1;
  // Short: every class must have training pixels for its mean; only the ontology's present classes.
  const Ontology fine = Ontology::builtin("rellis3d-fine");
  EXPECT_NE(error_of([&] { train_queries(sequence_->images, source, fine, nullptr, mean, with_means); })
                .find("has no training pixel to start its query from"),
            std::string::npos);
  train_queries(sequence_->images, source, o, nullptr, options(), with_means);  // kAuto without text: means
  EXPECT_NE(with_means.init.find("mean"), std::string::npos);
  EXPECT_GT(*with_means.epochs.back().val_accuracy, 0.85);
}

TEST_F(TrainQueriesTest, SameSeedGivesIdenticalVectors) {
  const Ontology o = Ontology::builtin("rellis3d-coarse");
  SimulatedTextEncoder text(encoder(3.f));
  const auto run = [&](uint64_t seed) {
    auto source = features();
    TrainQueriesOptions opt = options();
    opt.trainer.epochs = 1;
    opt.trainer.seed = seed;
    TrainQueriesReport report;
    return train_queries(sequence_->images, source, o, &text, opt, report).vectors;
  };
  const QueryMatrix a = run(7), b = run(7), c = run(8);
  EXPECT_EQ(std::memcmp(a.data(), b.data(), sizeof(float) * a.size()), 0);
  EXPECT_NE(std::memcmp(a.data(), c.data(), sizeof(float) * a.size()), 0);
}

TEST_F(TrainQueriesTest, RefusesMismatchedSpacesAndBadInput) {
  const Ontology o = Ontology::builtin("rellis3d-coarse");
  auto source = features();
  TrainQueriesReport report;
  SimulatedEncoderConfig other = encoder();
  other.dim = 32;
  SimulatedTextEncoder text32(other);
  EXPECT_NE(error_of([&] { train_queries(sequence_->images, source, o, &text32, options(), report); })
                .find("gives 32-d embeddings but the image features are 64-d"),
            std::string::npos);
  TrainQueriesOptions opt = options();
  opt.init = QueryInit::kText;
  EXPECT_NE(error_of([&] { train_queries(sequence_->images, source, o, nullptr, opt, report); }).find("needs a text encoder"),
            std::string::npos);
  opt = options();
  opt.val_fraction = 1.0;
  EXPECT_NE(error_of([&] { train_queries(sequence_->images, source, o, nullptr, opt, report); }).find("validation fraction"),
            std::string::npos);
  EXPECT_NE(error_of([&] { train_queries(std::span(sequence_->images).first(1), source, o, nullptr, options(), report); })
                .find("cannot be split"),
            std::string::npos);
  std::vector<ImageRecord> unlabelled(sequence_->images.begin(), sequence_->images.begin() + 3);
  for (auto& image : unlabelled) image.labels.clear();
  EXPECT_NE(error_of([&] { train_queries(unlabelled, source, o, nullptr, options(), report); }).find("none of the 3 images"),
            std::string::npos);

  // An ontology that does not list a label id of the data.
  const Ontology partial = Ontology::parse(R"(
name: partial
classes:
  - {name: ground, rgb: [0, 0, 0]}
labels:
  - {id: 3, name: grass, rgb: [0, 0, 0], class: ground}
)",
                                           "partial.yaml");
  EXPECT_NE(error_of([&] { train_queries(sequence_->images, source, partial, nullptr, options(), report); })
                .find("is not in ontology 'partial'"),
            std::string::npos);
}

// Precomputed .npy feature maps (as a network run offline would leave them) train the same way.
TEST_F(TrainQueriesTest, PrecomputedFeatureFilesTrainToo) {
  testing::TempDir npy;
  std::vector<ImageRecord> images = sequence_->images;
  auto simulated = features();
  for (auto& image : images) {
    image.features = npy.path / (image.labels.stem().string() + ".npy");
    write_feature_npy(image.features, simulated.features_for(image));
  }
  NpyFeatureSource files("lseg-offline");
  TrainQueriesReport report;
  const QuerySet q =
      train_queries(images, files, Ontology::builtin("rellis3d-coarse"), nullptr, options(), report);  // class means
  EXPECT_EQ(q.model_id, "lseg-offline");
  EXPECT_GT(*report.epochs.back().val_accuracy, 0.85);
}

struct CliRun {
  int status;
  std::string output;
};

CliRun run_cli(const std::string& args) {
  const fs::path log = fs::temp_directory_path() / fmt::format("slamvdb_train_cli_{}.txt", ::getpid());
  const int rc = std::system(fmt::format("{} {} > '{}' 2>&1", SLAMVDB_CLI_PATH, args, log.string()).c_str());
  std::ifstream in(log);
  CliRun r{WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, std::string(std::istreambuf_iterator<char>(in), {})};
  fs::remove(log);
  return r;
}

TEST_F(TrainQueriesTest, CommandsTrainEvaluateAndImport) {
  testing::TempDir out;
  const std::string seq = fmt::format("'{}'", dir_.string());
  const std::string q = (out.path / "q.json").string();
  const std::string common = " --dim 64 --feature-size 96x60 --pixels-per-image 256 --val-fraction 0.25";
  CliRun r = run_cli("train-queries " + seq + " -o '" + q + "' --epochs 2 --sim-text-gap 3" + common);
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("SIMULATED"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("initial queries: validation loss"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("epoch 2/2: train loss"), std::string::npos) << r.output;
  EXPECT_NE(r.output.find("images/s"), std::string::npos) << r.output;
  const QuerySet trained = load_query_set(q);
  EXPECT_EQ(trained.size(), 6);
  EXPECT_EQ(trained.provenance.epochs, 2);
  EXPECT_EQ(trained.provenance.notes.at("simulated"), "true");

  // The per-image baseline with those queries.
  const std::string md = (out.path / "t.md").string(), png = (out.path / "cm.png").string();
  r = run_cli("eval-images " + seq + " --queries '" + q + "' --dim 64 --feature-size 96x60 -o '" + md + "' --png '" +
              png + "' --json '" + md + ".json'");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_NE(r.output.find("| *rough* |"), std::string::npos) << r.output;
  EXPECT_TRUE(fs::exists(png));
  EXPECT_TRUE(fs::exists(md + ".json"));
  // Queries of another space are refused.
  r = run_cli("eval-images " + seq + " --queries '" + q + "' --dim 64 --feature-size 96x60 --sim-seed 2");
  EXPECT_EQ(r.status, 1) << r.output;
  EXPECT_NE(r.output.find("belong to model"), std::string::npos) << r.output;

  // CSV round trip through import-queries.
  export_query_csv_dir(trained, out.path / "csv");
  const std::string imported = (out.path / "imported.json").string();
  r = run_cli("import-queries '" + (out.path / "csv").string() + "' -o '" + imported + "' --model-id '" +
              trained.model_id + "' --ontology rellis3d-coarse");
  ASSERT_EQ(r.status, 0) << r.output;
  EXPECT_EQ(std::memcmp(load_query_set(imported).vectors.data(), trained.vectors.data(),
                        sizeof(float) * trained.vectors.size()),
            0);

  // Usage errors: refused before any work, naming the option.
  for (const auto& [args, expect] : std::vector<std::pair<std::string, std::string>>{
           {" --epochs -1", "--epochs"}, {" --features model --images 5:2", "--model"}}) {
    r = run_cli("train-queries " + seq + " -o '" + q + "'" + args);
    EXPECT_NE(r.status, 0) << args;
    EXPECT_NE(r.output.find(expect), std::string::npos) << args << ": " << r.output;
  }
  r = run_cli("train-queries " + seq + " -o '" + (out.path / "missing" / "q.json").string() + "'");
  EXPECT_NE(r.status, 0);
  EXPECT_NE(r.output.find("does not exist"), std::string::npos) << r.output;
}

}  // namespace
}  // namespace slamvdb
