#pragma once
// Segmentation scores over k classes (paper Table 6.1): counts of (ground truth, prediction)
// pairs, per-class recall, precision and IoU, recalled (predicted) and relevant (ground-truth)
// counts, overall accuracy and mIoU, with ignored classes (Void in the paper): an element whose
// ground truth is ignored is not scored at all; a prediction of an ignored class (possible when
// the void -> second-best rule is off) or no prediction (kNoPrediction) is a miss of the ground
// truth's class.
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace slamvdb {

struct ClassMetrics {
  std::string name;
  std::optional<double> hit;  // the paper's point-wise hit rate, filled by callers that have it
  std::optional<double> recall, precision, iou;  // fractions 0..1; empty when undefined (0 / 0)
  uint64_t recalled = 0;  // elements predicted as this class (ground truth not ignored)
  uint64_t relevant = 0;  // elements whose ground truth is this class
};

struct MetricsReport {
  std::optional<double> accuracy;  // correct / scored; empty when nothing was scored
  std::optional<double> miou;      // mean IoU over the reported classes with a defined IoU
  std::optional<double> hit_rate;  // overall hit rate, filled by callers that have it
  uint64_t scored = 0, ignored = 0, unpredicted = 0;
  std::vector<ClassMetrics> classes;  // the classes that are not ignored, in class order
  std::vector<std::string> ignored_classes;
};

class ConfusionMatrix {
 public:
  static constexpr int kNoPrediction = -1;

  // Throws Error on no classes, duplicate names or ignored indices out of range.
  ConfusionMatrix(std::vector<std::string> class_names, std::vector<int> ignored_classes = {});

  int num_classes() const { return static_cast<int>(names_.size()); }
  const std::vector<std::string>& class_names() const { return names_; }
  bool is_ignored(int k) const { return ignored_[k] != 0; }

  // truth in [0, k); predicted in [0, k) or kNoPrediction. Throws Error when out of range.
  void add(int truth, int predicted, uint64_t count = 1);
  // Throws Error unless both have the same classes and ignored classes.
  void merge(const ConfusionMatrix& other);

  uint64_t count(int truth, int predicted) const;  // predicted may be kNoPrediction
  uint64_t relevant(int k) const;     // scored elements whose ground truth is k
  uint64_t recalled(int k) const;     // scored elements predicted as k
  uint64_t true_positives(int k) const { return count(k, k); }
  uint64_t scored() const;            // elements with a ground truth that is not ignored
  uint64_t ignored() const { return ignored_count_; }

  std::optional<double> recall(int k) const;     // TP / relevant
  std::optional<double> precision(int k) const;  // TP / recalled
  std::optional<double> iou(int k) const;        // TP / (relevant + recalled - TP)
  std::optional<double> accuracy() const;
  std::optional<double> mean_iou() const;

  MetricsReport report() const;

 private:
  std::size_t cell(int truth, int predicted) const {  // column k is "no prediction"
    return static_cast<std::size_t>(truth) * (names_.size() + 1) +
           (predicted == kNoPrediction ? names_.size() : static_cast<std::size_t>(predicted));
  }

  std::vector<std::string> names_;
  std::vector<uint8_t> ignored_;
  std::vector<uint64_t> counts_;  // k x (k + 1), ignored ground truth rows stay zero
  uint64_t ignored_count_ = 0;
};

// Paper Table 6.1 as a markdown table: Class | Hit % | Recall % | Prec. % | IoU % | Recalled
// (x1000) | Relevant (x1000); an "all" row first (hit rate, accuracy, scored counts), then one row
// per class; blank where a value is undefined or (Hit) not given. A line with mIoU and what was
// ignored follows the table.
std::string to_markdown(const MetricsReport& report);
// {"accuracy", "miou", "hit_rate" (if given), "scored", "ignored", "unpredicted", "ignored_classes",
// "classes": {name: {"hit" (if given), "recall", "precision", "iou", "recalled", "relevant"}}};
// fractions 0..1, null when undefined.
std::string to_json(const MetricsReport& report);
// class,hit,recall,precision,iou,recalled,relevant (first row "all"); fractions, empty when undefined.
std::string to_csv(const MetricsReport& report);

// Several methods' scores side by side: a markdown table "Method | Scored | Accuracy % | mIoU %",
// one row per entry (`unit` names what was scored: "voxels", "pixels").
struct ScoredMethod {
  std::string name, unit;
  const ConfusionMatrix& matrix;
};
std::string comparison_markdown(const std::vector<ScoredMethod>& methods);

}  // namespace slamvdb
