#include "slamvdb/training/query_trainer.hpp"

#include <fmt/format.h>

#include <cmath>
#include <numeric>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/mix64.hpp"
#include "slamvdb/core/plugin_library.hpp"

namespace slamvdb {
namespace {

const QueryTrainerFactory& query_trainer_factory() {
#ifdef SLAMVDB_TORCH_TRAINING_PLUGIN
  static const QueryTrainerFactory& factory = plugin_exports<QueryTrainerFactory>(
      SLAMVDB_TORCH_TRAINING_PLUGIN, kQueryTrainerSymbol, "query training (libtorch)", kQueryTrainerVersion);
  return factory;
#else
  throw Error("query training needs libtorch: this slamvdb was built without it (SLAMVDB_WITH_TORCH=OFF)");
#endif
}

void check_samples(const PixelSamples& samples, int dim, int classes) {
  if (samples.dim() != dim) throw Error(fmt::format("{}-d samples for {}-d queries", samples.dim(), dim));
  for (int16_t t : samples.targets())
    if (t < 0 || t >= classes)
      throw Error(fmt::format("training target {} is not one of the {} query classes", t, classes));
}

}  // namespace

void validate(const TrainerOptions& o) {
  if (o.epochs < 0) throw Error(fmt::format("epochs must be >= 0, got {}", o.epochs));
  if (o.batch_size < 1) throw Error(fmt::format("batch size must be >= 1 pixel, got {}", o.batch_size));
  if (!(o.learning_rate > 0) || !std::isfinite(o.learning_rate))
    throw Error(fmt::format("learning rate must be > 0, got {}", o.learning_rate));
  if (!(o.temperature > 0) || !std::isfinite(o.temperature))
    throw Error(fmt::format("temperature must be > 0, got {}", o.temperature));
}

QueryTrainer::QueryTrainer(const QueryMatrix& initial, const TrainerOptions& options) : options_(options) {
  validate(options);
  if (initial.rows() < 1 || initial.cols() < 1) throw Error("query training needs at least one class and dimension");
  // Unit rows with the norm in double (query_set.hpp: no float overflow or underflow).
  QueryMatrix unit(initial.rows(), initial.cols());
  for (Eigen::Index k = 0; k < initial.rows(); ++k) {
    const auto row = unit_vector({initial.row(k).data(), static_cast<std::size_t>(initial.cols())});
    if (!row) throw Error(fmt::format("initial query {} is zero or not finite", k));
    unit.row(k) = row->transpose();
  }
  classes_ = static_cast<int>(unit.rows());
  dim_ = static_cast<int>(unit.cols());
  engine_ = query_trainer_factory().make(unit, options);
}

QueryTrainer::~QueryTrainer() = default;

double QueryTrainer::train_epoch(const PixelSamples& samples, const StepProgress& progress) {
  check_samples(samples, dim_, classes_);
  if (samples.size() == 0) throw Error("no training pixels");
  std::vector<std::size_t> order(samples.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  uint64_t state = mix64(options_.seed ^ mix64(0xE90C0000u + static_cast<uint64_t>(epoch_)));
  for (std::size_t i = order.size(); i > 1; --i) {  // Fisher-Yates with a portable generator
    state = mix64(state);
    std::swap(order[i - 1], order[state % i]);
  }
  const double mean_loss = engine_->train_epoch(samples, order, progress);
  ++epoch_;
  return mean_loss;
}

double QueryTrainer::loss(const PixelSamples& samples) const {
  check_samples(samples, dim_, classes_);
  if (samples.size() == 0) return 0.0;
  return engine_->loss(samples);
}

QueryMatrix QueryTrainer::queries() const { return engine_->queries(); }

int QueryTrainer::epochs_done() const { return epoch_; }

}  // namespace slamvdb
