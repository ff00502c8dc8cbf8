#pragma once
// The paper's evaluation of a semantic map (section 6.3.2, Table 6.1), void ignored as in the paper:
// - hit rate (Eq. 6.2): every labelled LiDAR point, moved into the world frame with the ground-
//   truth pose of its scan, that falls into a non-empty map voxel is counted; it is a hit when that
//   voxel's class (the map classified with the query set, void -> second-best) is the point's
//   coarse class. Per class: the share of that class's counted points that are hits.
// - voxel-wise labelling: each non-empty voxel takes the most frequent ground-truth class of the
//   points inside it, and recall, precision and IoU are computed over those voxels.
// A "non-empty voxel" is a cell of the map's global index that holds semantics (a voxel seen by the
// camera), as the paper's table counts them. Points of void classes neither count for the hit rate
// nor vote; a tie between classes goes to the class that comes first in the ontology; points with
// an unlabelled id are skipped; ids the ontology does not know are an error (a wrong ontology).
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/eval/confusion_matrix.hpp"
#include "slamvdb/map/semantic_map.hpp"
#include "slamvdb/ontology/ontology.hpp"
#include "slamvdb/query/map_query.hpp"

namespace slamvdb {

// One labelled scan of the evaluation sequence, loaded on demand (scans are read in parallel).
struct GroundTruthScan {
  Pose T_world_sensor;  // ground truth
  std::function<LidarScan()> load;  // points in the sensor frame with one label per point
  std::string name;                 // for messages
};

struct MapEvaluationOptions {
  ClassifyOptions classify;  // void -> second-best on by default
  ModelIdCheck model_check = ModelIdCheck::kRequireMatch;
};

struct MapEvaluation {
  MetricsReport report;       // voxel-wise metrics with the hit rates filled in (overall and per class)
  ConfusionMatrix voxels;     // ground truth (majority label) x predicted class, per non-empty voxel
  ConfusionMatrix points;     // ground truth x class of the voxel the point fell into
  uint64_t points_total = 0;  // points of the scans
  uint64_t points_unlabelled = 0, points_void = 0, points_outside = 0;  // skipped, by reason
  std::size_t scans = 0, map_cells = 0, cells_with_points = 0;
  // Per scored voxel: its voxel_confidence, whether its class was right (for accuracy_coverage and
  // calibration_table) and its position in classify_map's result for this map.
  struct ScoredVoxel {
    float confidence = 0.f;
    bool correct = false;
    std::size_t cell = 0;
  };
  std::vector<ScoredVoxel> scored_voxels{};
};

// The accuracy-coverage curve: for each fraction x, the voxel accuracy of the most confident x of
// the scored voxels (ties broken by storage order), with the lowest confidence taken in.
struct CoveragePoint {
  double fraction = 0, accuracy = 0;
  std::size_t voxels = 0;
  float min_confidence = 0;
};
std::vector<CoveragePoint> accuracy_coverage(const MapEvaluation& e,
                                             const std::vector<double>& fractions = {0.1, 0.25, 0.5, 0.75, 0.9, 1.0});
// "| Most confident | Voxels | Accuracy % | Confidence >= |" markdown table.
std::string coverage_markdown(const std::vector<CoveragePoint>& curve);
// The curve as a JSON array of {fraction, voxels, accuracy, min_confidence} (eval's and demo's
// `accuracy_coverage`).
std::string coverage_json(const std::vector<CoveragePoint>& curve);

// The calibration table: the scored voxels binned by confidence (bins of equal width over 0..1,
// the last one closed), each with its voxels, mean confidence and observed accuracy. A calibrated
// confidence has accuracy close to it; what matters for ranking is that accuracy rises with it.
struct CalibrationBin {
  double lower = 0, upper = 0;  // confidence range [lower, upper)
  std::size_t voxels = 0;
  double mean_confidence = 0, accuracy = 0;  // 0 for an empty bin
};
std::vector<CalibrationBin> calibration_table(const MapEvaluation& e, int bins = 10);
// "| Confidence | Voxels | Mean confidence | Accuracy % |" markdown table (empty bins left out).
std::string calibration_markdown(const std::vector<CalibrationBin>& table);
// JSON array of {lower, upper, voxels, mean_confidence, accuracy} (eval's `calibration`).
std::string calibration_json(const std::vector<CalibrationBin>& table);

using EvaluationProgress = std::function<void(std::size_t done, std::size_t total)>;

// Throws Error on queries from another embedding space, query names that are no ontology class,
// a scan whose labels do not match its points, or label ids the ontology does not know.
MapEvaluation evaluate_map(const SemanticMap& map, const std::vector<GroundTruthScan>& scans,
                           const QuerySet& queries, const Ontology& ontology,
                           const MapEvaluationOptions& options = {}, const EvaluationProgress& progress = {});

}  // namespace slamvdb
