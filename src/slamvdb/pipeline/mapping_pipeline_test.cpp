// End to end on a short simulated sequence: synth -> read -> map with the simulated encoder.
#include "slamvdb/pipeline/mapping_pipeline.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/ontology.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/image_io.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/map_cells.hpp"
#include "slamvdb/testing/pipeline_fixture.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::MappingPipelineTest;

TEST_F(MappingPipelineTest, BuildsASemanticMapAndFusionBeatsFewerViews) {
  const Sequence seq = read_sequence(dir_);
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                              EncoderFeatureSource::Input::kLabels);
  PipelineReport report;
  std::size_t last_progress = 0;
  const SemanticMap m = build_map(seq, &source, options(), report, [&](std::size_t d, std::size_t) { last_progress = d; });
  EXPECT_EQ(report.scans_integrated, seq.scans.size());
  EXPECT_EQ(last_progress, seq.scans.size());
  EXPECT_GT(report.images_total, 10u);
  EXPECT_EQ(report.images_fused + report.images_outside_pose_range, report.images_total);
  EXPECT_EQ(report.images_failed, 0u);
  EXPECT_EQ(report.inference.dropped_queue_full, 0u);  // replay policy: nothing lost
  EXPECT_GT(m.num_semantic_voxels(), 1000u);
  EXPECT_EQ(m.info().model_id, simulated_model_id(encoder_config()));
  const Correct all = correctness(m, seq);

  // The same drive with a fifth of the images: each voxel is fused from fewer views.
  Sequence sparse = seq;
  sparse.images.clear();
  for (std::size_t i = 0; i < seq.images.size(); i += 5) sparse.images.push_back(seq.images[i]);
  PipelineReport sparse_report;
  const SemanticMap few = build_map(sparse, &source, options(), sparse_report);
  const Correct fewer = correctness(few, seq);
  // On the voxels both maps labelled: more views per voxel, more voxels right.
  const double acc_all = accuracy(all, fewer), acc_few = accuracy(fewer, all);
  std::cout << "voxel accuracy on " << fewer.size() << " common voxels: all views " << acc_all
            << ", a fifth of the views " << acc_few << "; all views over " << all.size() << " voxels "
            << accuracy(all, all) << "\n";
  EXPECT_GT(accuracy(all, all), 0.70);
  EXPECT_GT(acc_all, acc_few + 0.03);
}

TEST_F(MappingPipelineTest, BadScansAreSkippedCountedAndReported) {
  Sequence seq = read_sequence(dir_);
  const fs::path bad_dir = dir_.parent_path() / (dir_.filename().string() + "_bad");
  fs::create_directories(bad_dir);
  // A truncated scan file and a scan with NaN points.
  const fs::path truncated = bad_dir / "000001.bin";
  fs::copy_file(seq.scans[1].points, truncated, fs::copy_options::overwrite_existing);
  fs::resize_file(truncated, fs::file_size(truncated) - 7);
  seq.scans[1].points = truncated;
  seq.scans[1].labels.clear();
  const fs::path with_nan = bad_dir / "000002.bin";
  {
    std::ofstream out(with_nan, std::ios::binary);
    const float p[8] = {std::numeric_limits<float>::quiet_NaN(), 1, 2, 0, 5, 0, -1, 0};
    out.write(reinterpret_cast<const char*>(p), sizeof p);
  }
  seq.scans[2].points = with_nan;
  seq.scans[2].labels.clear();
  PipelineOptions o = options();
  o.max_scans = 5;
  PipelineReport report;
  build_map(seq, nullptr, o, report);
  EXPECT_EQ(report.scans_failed, 1u);
  EXPECT_EQ(report.scans_integrated, 4u);
  EXPECT_EQ(report.points.dropped_nonfinite, 1u);
  ASSERT_FALSE(report.problems.empty());
  EXPECT_NE(report.problems[0].find("000001.bin"), std::string::npos);
  EXPECT_NE(report.summary().find("1 unreadable"), std::string::npos);
  fs::remove_all(bad_dir);
}

TEST_F(MappingPipelineTest, ImagesOutsideThePoseRangeAreReportedNotGuessed) {
  Sequence seq = read_sequence(dir_);
  ImageRecord early = seq.images.front(), late = seq.images.back();
  early.stamp = seq.scans.front().stamp - 5.0;
  late.stamp = seq.scans.back().stamp + 5.0;
  seq.images.insert(seq.images.begin(), early);
  seq.images.push_back(late);
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                              EncoderFeatureSource::Input::kLabels);
  PipelineReport report;
  build_map(seq, &source, options(), report);
  EXPECT_EQ(report.images_total, seq.images.size());
  EXPECT_EQ(report.images_outside_pose_range, 2u);
  EXPECT_EQ(report.images_fused + 2, report.images_total);
}

TEST_F(MappingPipelineTest, WrongFeatureDimensionIsAClearError) {
  const Sequence seq = read_sequence(dir_);
  SimulatedEncoderConfig c = encoder_config();
  c.dim = 32;
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(c), EncoderFeatureSource::Input::kLabels);
  PipelineOptions o = options();
  o.max_scans = 10;
  PipelineReport report;
  try {
    build_map(seq, &source, o, report);
    FAIL() << "expected an error";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("32 channels"), std::string::npos) << e.what();
  }
}


}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

// The measurement behind the fp16 default: the same replay stored in fp16 and in fp32 gives
// embeddings with the same direction and the same best class for (nearly) every voxel.
TEST_F(MappingPipelineTest, Fp16StorageKeepsTheFp32Answer) {
  const Sequence seq = read_sequence(dir_);
  // 512-d, as the paper; the clean encoder by name: storage precision, not the failure modes, is measured
  const SimulatedEncoderConfig enc = SimulatedEncoderConfig::clean();
  PipelineOptions o;
  o.max_scans = 30;
  o.map.semantic.precision = EmbeddingPrecision::kFloat32;
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(enc), EncoderFeatureSource::Input::kLabels);
  PipelineReport r32, r16;
  const SemanticMap full = build_map(seq, &source, o, r32);
  o.map.semantic.precision = EmbeddingPrecision::kFloat16;
  const SemanticMap half = build_map(seq, &source, o, r16);
  const auto a = testing::index_cells(full), b = testing::index_cells(half);
  ASSERT_EQ(a.size(), b.size());
  ASSERT_GT(a.size(), 1000u);
  const auto protos = simulated_class_prototypes(enc);
  double min_cos = 1.0;
  std::size_t same_class = 0;
  for (const auto& [k, ca] : a) {
    const auto it = b.find(k);
    ASSERT_NE(it, b.end());
    const Eigen::Map<const Eigen::VectorXf> ea(ca.embedding.data(), 512), eb(it->second.embedding.data(), 512);
    min_cos = std::min(min_cos, static_cast<double>(ea.dot(eb) / (ea.norm() * eb.norm())));
    Eigen::Index ia, ib;
    (protos * ea).maxCoeff(&ia);
    (protos * eb).maxCoeff(&ib);
    same_class += ia == ib;
  }
  const double agreement = static_cast<double>(same_class) / a.size();
  const double bytes_a = testing::semantic_bytes_per_entry(full), bytes_b = testing::semantic_bytes_per_entry(half);
  std::cout << "fp16 vs fp32 over " << a.size() << " cells: min cosine " << min_cos << ", same class "
            << agreement * 100 << "%, bytes/voxel " << bytes_b << " vs " << bytes_a << "\n";
  EXPECT_GT(min_cos, 0.9999);
  EXPECT_GT(agreement, 0.999);
  EXPECT_LT(bytes_b, 0.6 * bytes_a);
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

// Features computed offline and stored as features/<image stem>.npy (C x H x W) give the same
// map as computing them in the pipeline.
TEST_F(MappingPipelineTest, PrecomputedNpyFeaturesGiveTheSameMap) {
  const fs::path copy = dir_.parent_path() / (dir_.filename().string() + "_npy");
  fs::remove_all(copy);
  fs::copy(dir_, copy, fs::copy_options::recursive);
  SimulatedDenseEncoder encoder(encoder_config());
  const Sequence original = read_sequence(copy);
  fs::create_directories(copy / "features");
  for (const auto& img : original.images)
    write_feature_npy(copy / "features" / (img.labels.stem().string() + ".npy"),
                      encoder.encode(load_image_frame(img, false, true)));
  const Sequence seq = read_sequence(copy);
  ASSERT_FALSE(seq.images.front().features.empty());
  PipelineOptions o = options();
  o.max_scans = 20;
  NpyFeatureSource npy("precomputed-test");
  EncoderFeatureSource live(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                            EncoderFeatureSource::Input::kLabels);
  PipelineReport ra, rb;
  const SemanticMap a = build_map(seq, &npy, o, ra);
  const SemanticMap b = build_map(seq, &live, o, rb);
  EXPECT_GT(ra.images_fused, 5u);
  EXPECT_EQ(ra.images_fused, rb.images_fused);
  const auto ca = testing::index_cells(a), cb = testing::index_cells(b);
  ASSERT_EQ(ca.size(), cb.size());
  for (const auto& [k, cell] : ca) {
    const auto t = cb.find(k);
    ASSERT_NE(t, cb.end());
    EXPECT_EQ(cell.embedding, t->second.embedding);
    EXPECT_EQ(cell.count, t->second.count);
  }
  EXPECT_EQ(a.info().model_id, "precomputed-test");
  fs::remove_all(copy);
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

// The round trip: synth -> map -> save -> load gives back the same map.
TEST_F(MappingPipelineTest, SynthMapSaveLoadRoundTrip) {
  const Sequence seq = read_sequence(dir_);
  EncoderFeatureSource source(std::make_unique<SimulatedDenseEncoder>(encoder_config()),
                              EncoderFeatureSource::Input::kLabels);
  PipelineOptions o = options();
  o.max_scans = 20;
  PipelineReport report;
  const SemanticMap built = build_map(seq, &source, o, report);
  const fs::path file = dir_.parent_path() / (dir_.filename().string() + ".svdb");
  save_map(file, built);
  const SemanticMap loaded = load_map(file);
  EXPECT_EQ(loaded.info().model_id, built.info().model_id);
  EXPECT_EQ(loaded.params().semantic.dim, 64);
  EXPECT_EQ(loaded.num_submaps(), built.num_submaps());
  EXPECT_GE(built.num_submaps(), 1u);
  EXPECT_EQ(loaded.num_known_voxels(), built.num_known_voxels());
  EXPECT_EQ(loaded.num_occupied_voxels(), built.num_occupied_voxels());
  ASSERT_EQ(loaded.num_semantic_voxels(), built.num_semantic_voxels());
  const auto a = testing::index_cells(built), b = testing::index_cells(loaded);
  ASSERT_EQ(a.size(), b.size());
  for (const auto& [k, cell] : a) {
    const auto t = b.find(k);
    ASSERT_NE(t, b.end());
    EXPECT_EQ(cell.count, t->second.count);
    EXPECT_EQ(cell.embedding, t->second.embedding);
  }
  const auto wa = built.world_occupancy(), wb = loaded.world_occupancy();
  ASSERT_EQ(wa.size(), wb.size());
  for (std::size_t i = 0; i < wa.size(); ++i) {
    EXPECT_EQ(wa[i].cell, wb[i].cell);
    EXPECT_EQ(wa[i].log_odds, wb[i].log_odds);
  }
  fs::remove(file);
}

}  // namespace
}  // namespace slamvdb

namespace slamvdb {
namespace {

int run_cli(const std::string& args, std::string* output) {
  const fs::path log = fs::temp_directory_path() / ("slamvdb_cli_" + std::to_string(::getpid()) + ".txt");
  const int rc = std::system((std::string(SLAMVDB_CLI_PATH) + " " + args + " > '" + log.string() + "' 2>&1").c_str());
  std::ifstream in(log);
  output->assign(std::istreambuf_iterator<char>(in), {});
  fs::remove(log);
  return rc;
}

TEST_F(MappingPipelineTest, MapCommandNamesTheSimulationAndRejectsBadOptions) {
  const fs::path map = dir_.parent_path() / (dir_.filename().string() + "_cli.svdb");
  std::string out;
  ASSERT_EQ(run_cli("map '" + dir_.string() + "' -o '" + map.string() + "' --max-scans 10 --dim 64", &out), 0) << out;
  EXPECT_NE(out.find("SIMULATED"), std::string::npos) << out;
  EXPECT_NE(out.find("10 integrated of 10"), std::string::npos) << out;
  EXPECT_TRUE(fs::exists(map));
  EXPECT_NE(run_cli("map '" + dir_.string() + "' -o '" + map.string() + "' --precision fp8", &out), 0);
  EXPECT_NE(out.find("fp8"), std::string::npos) << out;
  EXPECT_NE(run_cli("map '" + dir_.string() + "' -o '" + map.string() + "' --features magic", &out), 0);
  EXPECT_NE(out.find("magic"), std::string::npos) << out;
  EXPECT_NE(run_cli("map /nonexistent/seq -o '" + map.string() + "'", &out), 0);
  EXPECT_EQ(run_cli("map --help", &out), 0);
  EXPECT_NE(out.find("--max-clearing-range"), std::string::npos);
  fs::remove(map);
}

}  // namespace
}  // namespace slamvdb
