#pragma once
// Query-vector optimisation (paper section 6.2.5, Figure 6.4): the n x dim query matrix is the
// only parameter; the encoders stay frozen. Loss as in LSeg: softmax cross-entropy over the
// temperature-scaled cosine similarities of each pixel's feature with every query. libtorch's
// autograd and Adam do the optimisation, in the TorchScript backend's plugin library
// (query_trainer_torch.cpp, loaded on first use: core/plugin_library.hpp); this side, with the
// checks and the shuffling, includes no torch header.
#include <cstdint>
#include <functional>
#include <memory>
#include <span>

#include "slamvdb/query/query_set.hpp"
#include "slamvdb/training/pixel_samples.hpp"

namespace slamvdb {

struct TrainerOptions {
  int epochs = 2;           // the paper's shipped queries: two epochs
  int batch_size = 4096;    // pixels per optimiser step, drawn shuffled across all training images
  double learning_rate = 1e-2;
  double temperature = 0.07;  // logits = cosine / temperature (CLIP's and LSeg's 1 / 14.3)
  uint64_t seed = 1;
};

void validate(const TrainerOptions& options);  // throws Error naming the bad option

using StepProgress = std::function<void(std::size_t done, std::size_t total)>;

class QueryTrainer {
 public:
  // Throws Error on bad options or an invalid initial matrix (non-finite or zero rows).
  QueryTrainer(const QueryMatrix& initial, const TrainerOptions& options);
  ~QueryTrainer();
  QueryTrainer(const QueryTrainer&) = delete;
  QueryTrainer& operator=(const QueryTrainer&) = delete;

  // One pass over `samples` in batches, shuffled by (seed, epoch); returns the mean loss over the
  // pass. Single-threaded torch, so the result is the same on every run for a seed.
  double train_epoch(const PixelSamples& samples, const StepProgress& progress = {});
  // Mean loss over `samples` with the current queries, without gradients.
  double loss(const PixelSamples& samples) const;
  // The current queries, rows L2-normalised.
  QueryMatrix queries() const;
  int epochs_done() const;

 private:
  std::unique_ptr<class QueryTrainerEngine> engine_;
  TrainerOptions options_;
  int classes_ = 0, dim_ = 0, epoch_ = 0;
};

// What the backend implements, after QueryTrainer's checks: the optimiser over rows that are unit
// vectors, in batches of the given order.
class QueryTrainerEngine {
 public:
  virtual ~QueryTrainerEngine() = default;
  virtual double train_epoch(const PixelSamples& samples, std::span<const std::size_t> order,
                             const StepProgress& progress) = 0;
  virtual double loss(const PixelSamples& samples) const = 0;
  virtual QueryMatrix queries() const = 0;
};

// What the backend library exports, by kQueryTrainerSymbol; the version is checked.
struct QueryTrainerFactory {
  int version = 0;
  std::unique_ptr<QueryTrainerEngine> (*make)(const QueryMatrix& unit_rows, const TrainerOptions& options) = nullptr;
};
inline constexpr int kQueryTrainerVersion = 1;
inline constexpr const char* kQueryTrainerSymbol = "slamvdb_query_trainer_factory";

}  // namespace slamvdb
