#pragma once
// Query-vector optimisation (paper section 6.2.5, Figure 6.4): the n x dim query matrix is the
// only parameter; the encoders stay frozen. Loss as in LSeg: softmax cross-entropy over the
// temperature-scaled cosine similarities of each pixel's feature with every query. libtorch's
// autograd and Adam do the optimisation; only query_trainer.cpp includes torch headers.
#include <cstdint>
#include <functional>
#include <memory>

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
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace slamvdb
