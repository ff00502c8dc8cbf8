#pragma once
// Test fixture for the mapping pipeline: a short SIMULATED sequence generated once per suite, and
// voxel-wise correctness of a map against the majority label of the ground-truth points.
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <map>
#include <tuple>

#include "slamvdb/core/ontology.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/pipeline/mapping_pipeline.hpp"
#include "slamvdb/synth/sequence_writer.hpp"
#include "slamvdb/testing/test_scale.hpp"

namespace slamvdb::testing {
namespace fs = std::filesystem;

class MappingPipelineTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = fs::temp_directory_path() / ("slamvdb_pipeline_test_" + std::to_string(::getpid()));
    synth::SynthConfig config;
    config.seed = 11;
    config.length_m = 30.0;
    config.image_width = 320;
    config.image_height = 200;
    config.lidar.columns = test_size(1024, 256);  // testing/test_scale.hpp
    synth::write_synthetic_sequence(config, dir_, true);
  }
  static void TearDownTestSuite() { fs::remove_all(dir_); }

  static PipelineOptions options() {
    PipelineOptions o;
    o.map.semantic.dim = 64;  // small and fast; the pipeline is dimension-agnostic
    return o;
  }
  // The clean SIMULATED encoder: these tests measure the mapping mechanics (fusion against fewer
  // views, occlusion choices) with the ideal text queries, not the realistic failure modes
  // (eval/honest_accuracy_test.cpp does that).
  static SimulatedEncoderConfig encoder_config() {
    SimulatedEncoderConfig c = SimulatedEncoderConfig::clean();
    c.dim = 64;
    return c;
  }

  // Voxel-wise correctness against the majority label of the ground-truth points in each voxel
  // (the paper's voxel labelling), predicting the class whose prototype is most similar.
  using Correct = std::map<std::tuple<int, int, int>, bool>;
  static Correct correctness(const SemanticMap& m, const Sequence& seq) {
    Correct out;
    m.read_index([&](const GlobalIndex& index) {
      std::map<std::tuple<int, int, int>, std::map<uint16_t, int>> votes;
      for (const auto& rec : seq.scans) {
        const LidarScan scan = read_scan(rec);
        const Pose T = *seq.poses.at(rec.stamp);
        for (std::size_t i = 0; i < scan.points.size(); ++i) {
          const IndexCellKey k = index.cell_of(T * scan.points[i].cast<double>());
          ++votes[{k.x(), k.y(), k.z()}][scan.labels[i]];
        }
      }
      const auto protos = simulated_class_prototypes(encoder_config());
      std::vector<float> scratch(index.dim()), v(index.dim());
      for (std::size_t i = 0; i < index.size(); ++i) {
        const IndexedVoxel cell = index.read(i, scratch.data());
        const IndexCellKey& k = cell.cell;
        const auto it = votes.find({k.x(), k.y(), k.z()});
        if (it == votes.end()) continue;
        uint16_t truth = 0;
        int best_votes = -1;
        for (const auto& [label, n] : it->second)
          if (n > best_votes) truth = label, best_votes = n;
        kernels::decode(cell.embedding, v.data(), v.size());
        const Eigen::Map<const Eigen::VectorXf> e(v.data(), index.dim());
        Eigen::Index best;
        (protos * e).maxCoeff(&best);
        out[{k.x(), k.y(), k.z()}] = rellis_classes()[best].id == truth;
      }
    });
    return out;
  }
  // Accuracy over the voxels of `c` that are also in `within`.
  static double accuracy(const Correct& c, const Correct& within) {
    std::size_t right = 0, total = 0;
    for (const auto& [k, ok] : c)
      if (within.count(k)) right += ok, ++total;
    return total ? static_cast<double>(right) / total : 0.0;
  }

  static inline fs::path dir_;
};

}  // namespace slamvdb::testing
