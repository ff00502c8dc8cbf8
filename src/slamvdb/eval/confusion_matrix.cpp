#include "slamvdb/eval/confusion_matrix.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <nlohmann/json.hpp>
#include <set>

#include "slamvdb/core/csv.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"

namespace slamvdb {
namespace {

std::optional<double> ratio(uint64_t num, uint64_t den) {
  if (den == 0) return std::nullopt;
  return static_cast<double>(num) / static_cast<double>(den);
}

}  // namespace

ConfusionMatrix::ConfusionMatrix(std::vector<std::string> class_names, std::vector<int> ignored_classes)
    : names_(std::move(class_names)) {
  if (names_.empty()) throw Error("a confusion matrix needs at least one class");
  std::set<std::string> seen;
  for (const auto& n : names_)
    if (!seen.insert(n).second) throw Error(fmt::format("confusion matrix: class '{}' appears twice", n));
  ignored_.assign(names_.size(), 0);
  for (int k : ignored_classes) {
    if (k < 0 || k >= num_classes())
      throw Error(fmt::format("confusion matrix: ignored class {} is out of range [0, {})", k, num_classes()));
    ignored_[k] = 1;
  }
  counts_.assign(names_.size() * (names_.size() + 1), 0);
}

void ConfusionMatrix::add(int truth, int predicted, uint64_t count) {
  if (truth < 0 || truth >= num_classes())
    throw Error(fmt::format("confusion matrix: ground-truth class {} is out of range [0, {})", truth, num_classes()));
  if (predicted != kNoPrediction && (predicted < 0 || predicted >= num_classes()))
    throw Error(fmt::format("confusion matrix: predicted class {} is out of range [0, {})", predicted, num_classes()));
  if (ignored_[truth]) {
    ignored_count_ += count;
    return;
  }
  counts_[cell(truth, predicted)] += count;
}

void ConfusionMatrix::merge(const ConfusionMatrix& other) {
  if (other.names_ != names_ || other.ignored_ != ignored_)
    throw Error("confusion matrices with different classes cannot be merged");
  for (std::size_t i = 0; i < counts_.size(); ++i) counts_[i] += other.counts_[i];
  ignored_count_ += other.ignored_count_;
}

uint64_t ConfusionMatrix::count(int truth, int predicted) const { return counts_.at(cell(truth, predicted)); }

uint64_t ConfusionMatrix::relevant(int k) const {
  uint64_t n = 0;
  for (int p = 0; p < num_classes(); ++p) n += count(k, p);
  return n + count(k, kNoPrediction);
}

uint64_t ConfusionMatrix::recalled(int k) const {
  uint64_t n = 0;
  for (int t = 0; t < num_classes(); ++t) n += count(t, k);
  return n;
}

uint64_t ConfusionMatrix::scored() const {
  uint64_t n = 0;
  for (uint64_t c : counts_) n += c;
  return n;
}

std::optional<double> ConfusionMatrix::recall(int k) const { return ratio(true_positives(k), relevant(k)); }
std::optional<double> ConfusionMatrix::precision(int k) const { return ratio(true_positives(k), recalled(k)); }
std::optional<double> ConfusionMatrix::iou(int k) const {
  return ratio(true_positives(k), relevant(k) + recalled(k) - true_positives(k));
}

std::optional<double> ConfusionMatrix::accuracy() const {
  uint64_t correct = 0;
  for (int k = 0; k < num_classes(); ++k) correct += true_positives(k);
  return ratio(correct, scored());
}

std::optional<double> ConfusionMatrix::mean_iou() const {
  double sum = 0;
  int n = 0;
  for (int k = 0; k < num_classes(); ++k) {
    if (ignored_[k]) continue;
    if (const auto v = iou(k)) sum += *v, ++n;
  }
  if (n == 0) return std::nullopt;
  return sum / n;
}

MetricsReport ConfusionMatrix::report() const {
  MetricsReport r;
  r.accuracy = accuracy();
  r.miou = mean_iou();
  r.scored = scored();
  r.ignored = ignored_count_;
  for (int k = 0; k < num_classes(); ++k) r.unpredicted += count(k, kNoPrediction);
  for (int k = 0; k < num_classes(); ++k) {
    if (ignored_[k]) {
      r.ignored_classes.push_back(names_[k]);
      continue;
    }
    r.classes.push_back({names_[k], std::nullopt, recall(k), precision(k), iou(k), recalled(k), relevant(k)});
  }
  return r;
}

std::string to_markdown(const MetricsReport& r) {
  const auto pct = [](const std::optional<double>& v) { return v ? fmt::format("{:.2f}", 100.0 * *v) : std::string(); };
  const auto thousands = [](uint64_t n) { return fmt::format("{:.2f}", n / 1000.0); };
  std::string out = "| Class | Hit % | Recall % | Prec. % | IoU % | Recalled (x1000) | Relevant (x1000) |\n"
                    "|---|---:|---:|---:|---:|---:|---:|\n";
  out += fmt::format("| *all* | {} | {} |  |  | {} | {} |\n", pct(r.hit_rate), pct(r.accuracy), thousands(r.scored),
                     thousands(r.scored));
  for (const auto& c : r.classes)
    out += fmt::format("| *{}* | {} | {} | {} | {} | {} | {} |\n", markdown_cell(c.name), pct(c.hit), pct(c.recall),
                       pct(c.precision), pct(c.iou), thousands(c.recalled), thousands(c.relevant));
  out += fmt::format("\nmIoU {} % over the classes with a defined IoU; \"all\" recall = overall accuracy.", pct(r.miou));
  if (!r.ignored_classes.empty()) {
    std::vector<std::string> ignored;
    for (const std::string& name : r.ignored_classes) ignored.push_back(markdown_cell(name));
    out += fmt::format(" Ignored: {} ({} elements).", fmt::join(ignored, ", "), r.ignored);
  }
  if (r.unpredicted > 0) out += fmt::format(" {} scored elements had no prediction (counted as misses).", r.unpredicted);
  return out + "\n";
}

std::string to_json(const MetricsReport& r) {
  using nlohmann::json;
  const auto value = [](const std::optional<double>& v) { return v ? json(*v) : json(nullptr); };
  json classes = json::object();
  for (const auto& c : r.classes) {
    json j = {{"recall", value(c.recall)}, {"precision", value(c.precision)}, {"iou", value(c.iou)},
              {"recalled", c.recalled},    {"relevant", c.relevant}};
    if (c.hit) j["hit"] = *c.hit;
    classes[c.name] = std::move(j);
  }
  json doc = {{"accuracy", value(r.accuracy)}, {"miou", value(r.miou)},           {"scored", r.scored},
              {"ignored", r.ignored},          {"unpredicted", r.unpredicted},   {"ignored_classes", r.ignored_classes},
              {"classes", std::move(classes)}};
  if (r.hit_rate) doc["hit_rate"] = *r.hit_rate;
  return doc.dump(2) + "\n";
}

std::string to_csv(const MetricsReport& r) {
  const auto v = [](const std::optional<double>& x) { return x ? fmt::format("{:.6f}", *x) : std::string(); };
  CsvWriter csv({"class", "hit", "recall", "precision", "iou", "recalled", "relevant"});
  csv.row({"all", v(r.hit_rate), v(r.accuracy), "", "", fmt::format("{}", r.scored), fmt::format("{}", r.scored)});
  for (const auto& c : r.classes)
    csv.row({c.name, v(c.hit), v(c.recall), v(c.precision), v(c.iou), fmt::format("{}", c.recalled),
             fmt::format("{}", c.relevant)});
  return csv.text();
}

std::string comparison_markdown(const std::vector<ScoredMethod>& methods) {
  std::string out = "| Method | Scored | Accuracy % | mIoU % |\n|---|---:|---:|---:|\n";
  const auto percent = [](std::optional<double> v) { return v ? fmt::format("{:.2f}", 100 * *v) : std::string(); };
  for (const ScoredMethod& m : methods)
    out += fmt::format("| {} | {} {} | {} | {} |\n", m.name, m.matrix.scored(), m.unit, percent(m.matrix.accuracy()),
                       percent(m.matrix.mean_iou()));
  return out;
}

}  // namespace slamvdb
