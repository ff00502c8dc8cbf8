#include "slamvdb/eval/map_evaluation.hpp"

#include <fmt/format.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <mutex>
#include <nlohmann/json.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/eval/pixel_scoring.hpp"
#include "slamvdb/query/class_confidence.hpp"

namespace slamvdb {

MapEvaluation evaluate_map(const SemanticMap& map, const std::vector<GroundTruthScan>& scans,
                           const QuerySet& queries, const Ontology& ontology, const MapEvaluationOptions& options,
                           const EvaluationProgress& progress) {
  const std::vector<int> class_of_query = ontology_classes_of(queries, ontology);
  const std::vector<ClassifiedCell> cells = classify_map(map, queries, options.classify, options.model_check);
  const int k = ontology.num_classes();
  const LabelMapping truth_of = ontology.ground_truth();

  MapEvaluation result{{}, ontology_confusion_matrix(ontology), ontology_confusion_matrix(ontology)};
  result.scans = scans.size();
  result.map_cells = cells.size();
  // Per non-empty voxel (index position), one vote counter per class.
  std::vector<uint32_t> votes(cells.size() * static_cast<std::size_t>(k), 0);

  struct Local {
    ConfusionMatrix points;
    uint64_t total = 0, unlabelled = 0, is_void = 0, outside = 0;
  };
  tbb::enumerable_thread_specific<Local> locals([&] { return Local{ontology_confusion_matrix(ontology)}; });
  std::atomic<std::size_t> done{0};
  std::mutex progress_mutex;
  map.read_index([&](const GlobalIndex& index) {
    if (index.size() != cells.size()) throw Error("the map changed during the evaluation");
    tbb::parallel_for(std::size_t{0}, scans.size(), [&](std::size_t s) {
      const GroundTruthScan& gt = scans[s];
      const LidarScan scan = gt.load();
      if (scan.labels.size() != scan.points.size())
        throw Error(fmt::format("scan {} has {} points but {} labels", gt.name, scan.points.size(), scan.labels.size()));
      Local& local = locals.local();
      for (std::size_t i = 0; i < scan.points.size(); ++i) {
        ++local.total;
        const int truth = truth_of(scan.labels[i]);
        if (truth == LabelMapping::kIgnore) {
          ++local.unlabelled;
          continue;
        }
        if (truth == LabelMapping::kUnknown)
          throw Error(fmt::format("scan {} has label id {}, which ontology {} does not know", gt.name, scan.labels[i],
                                  ontology.name()));
        if (ontology.is_void(truth)) {
          ++local.is_void;
          continue;
        }
        const Vec3f& p = scan.points[i];
        if (!p.allFinite() || (p.x() == 0 && p.y() == 0 && p.z() == 0)) {  // no return
          ++local.unlabelled;
          continue;
        }
        const Vec3d p_world = gt.T_world_sensor * p.cast<double>();
        if (!in_grid_extent(p_world / index.cell_size())) {
          ++local.outside;
          continue;
        }
        const auto at = index.find(index.cell_of(p_world));
        if (!at) {
          ++local.outside;
          continue;
        }
        const QueryMatch& m = cells[*at].match;
        const int predicted = m.class_index == kNoClass ? ConfusionMatrix::kNoPrediction : class_of_query[m.class_index];
        local.points.add(truth, predicted);
        std::atomic_ref<uint32_t>(votes[*at * static_cast<std::size_t>(k) + static_cast<std::size_t>(truth)])
            .fetch_add(1, std::memory_order_relaxed);
      }
      if (progress) {
        const std::size_t n = ++done;
        std::lock_guard lock(progress_mutex);
        progress(n, scans.size());
      }
    });
  });
  for (const Local& local : locals) {
    result.points.merge(local.points);
    result.points_total += local.total;
    result.points_unlabelled += local.unlabelled;
    result.points_void += local.is_void;
    result.points_outside += local.outside;
  }

  // Voxel-wise labelling: the majority class of the points in each voxel (first class on a tie).
  for (std::size_t c = 0; c < cells.size(); ++c) {
    const uint32_t* v = votes.data() + c * static_cast<std::size_t>(k);
    int truth = -1;
    uint32_t best = 0;
    for (int j = 0; j < k; ++j)
      if (v[j] > best) best = v[j], truth = j;
    if (truth < 0) continue;
    ++result.cells_with_points;
    const QueryMatch& m = cells[c].match;
    const int predicted = m.class_index == kNoClass ? ConfusionMatrix::kNoPrediction : class_of_query[m.class_index];
    result.voxels.add(truth, predicted);
    if (!result.voxels.is_ignored(truth))
      result.scored_voxels.push_back({cells[c].confidence, predicted == truth, c});
  }

  result.report = result.voxels.report();
  result.report.hit_rate = result.points.accuracy();
  for (ClassMetrics& cm : result.report.classes)
    if (const auto j = ontology.find_class(cm.name)) cm.hit = result.points.recall(*j);
  return result;
}

std::vector<CoveragePoint> accuracy_coverage(const MapEvaluation& e, const std::vector<double>& fractions) {
  std::vector<MapEvaluation::ScoredVoxel> v = e.scored_voxels;
  std::stable_sort(v.begin(), v.end(), [](const auto& a, const auto& b) { return a.confidence > b.confidence; });
  std::vector<CoveragePoint> curve;
  for (const double f : fractions) {
    const auto n = static_cast<std::size_t>(std::llround(std::clamp(f, 0.0, 1.0) * static_cast<double>(v.size())));
    if (n == 0) continue;
    std::size_t right = 0;
    for (std::size_t i = 0; i < n; ++i) right += v[i].correct;
    curve.push_back({f, static_cast<double>(right) / static_cast<double>(n), n, v[n - 1].confidence});
  }
  return curve;
}

std::string coverage_markdown(const std::vector<CoveragePoint>& curve) {
  std::string out = "| Most confident | Voxels | Accuracy % | Confidence >= |\n|---:|---:|---:|---:|\n";
  for (const CoveragePoint& p : curve)
    out += fmt::format("| {:.0f} % | {} | {:.2f} | {:.3f} |\n", 100 * p.fraction, p.voxels, 100 * p.accuracy,
                       p.min_confidence);
  return out;
}

std::string coverage_json(const std::vector<CoveragePoint>& curve) {
  nlohmann::json array = nlohmann::json::array();
  for (const CoveragePoint& p : curve)
    array.push_back(
        {{"fraction", p.fraction}, {"voxels", p.voxels}, {"accuracy", p.accuracy}, {"min_confidence", p.min_confidence}});
  return array.dump();
}

std::vector<CalibrationBin> calibration_table(const MapEvaluation& e, int bins) {
  if (bins < 1) throw Error(fmt::format("calibration table: {} bins (at least 1)", bins));
  std::vector<CalibrationBin> table(static_cast<std::size_t>(bins));
  std::vector<double> confidence_sum(table.size(), 0.0);
  std::vector<std::size_t> right(table.size(), 0);
  for (std::size_t b = 0; b < table.size(); ++b)
    table[b].lower = static_cast<double>(b) / bins, table[b].upper = static_cast<double>(b + 1) / bins;
  for (const MapEvaluation::ScoredVoxel& v : e.scored_voxels) {
    const double c = std::isfinite(v.confidence) ? std::clamp(static_cast<double>(v.confidence), 0.0, 1.0) : 0.0;
    const auto b = std::min(table.size() - 1, static_cast<std::size_t>(c * bins));
    ++table[b].voxels;
    confidence_sum[b] += c;
    right[b] += v.correct;
  }
  for (std::size_t b = 0; b < table.size(); ++b)
    if (table[b].voxels) {
      table[b].mean_confidence = confidence_sum[b] / static_cast<double>(table[b].voxels);
      table[b].accuracy = static_cast<double>(right[b]) / static_cast<double>(table[b].voxels);
    }
  return table;
}

std::string calibration_markdown(const std::vector<CalibrationBin>& table) {
  std::string out = "| Confidence | Voxels | Mean confidence | Accuracy % |\n|---|---:|---:|---:|\n";
  for (const CalibrationBin& b : table)
    if (b.voxels)
      out += fmt::format("| {:.1f}-{:.1f} | {} | {:.3f} | {:.2f} |\n", b.lower, b.upper, b.voxels, b.mean_confidence,
                         100 * b.accuracy);
  return out;
}

std::string calibration_json(const std::vector<CalibrationBin>& table) {
  nlohmann::json array = nlohmann::json::array();
  for (const CalibrationBin& b : table)
    array.push_back({{"lower", b.lower},
                     {"upper", b.upper},
                     {"voxels", b.voxels},
                     {"mean_confidence", b.mean_confidence},
                     {"accuracy", b.accuracy}});
  return array.dump();
}

}  // namespace slamvdb
