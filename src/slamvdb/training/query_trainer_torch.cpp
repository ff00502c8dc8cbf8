// The query trainer's libtorch side (query_trainer.hpp's QueryTrainerEngine), built into the plugin
// library libslamvdb_torch_training.so that QueryTrainer loads on first use.
#include <torch/torch.h>

#include <algorithm>

#include "slamvdb/training/query_trainer.hpp"

namespace slamvdb {
namespace {

namespace F = torch::nn::functional;

// One torch thread while optimising: the products are tiny (batch x dim x classes), and a fixed
// thread count keeps every reduction in the same order, so a seed gives the same vectors.
class SingleThreadedTorch {
 public:
  SingleThreadedTorch() : saved_(at::get_num_threads()) { at::set_num_threads(1); }
  ~SingleThreadedTorch() { at::set_num_threads(saved_); }

 private:
  int saved_;
};

// fp16 rows -> an fp32 tensor; torch's conversion is vectorised for the CPU it runs on (the
// scalar fp16 decoding of a portable build took most of an epoch).
torch::Tensor half_rows(const uint16_t* data, std::size_t rows, int64_t dim) {
  return torch::from_blob(const_cast<uint16_t*>(data), {static_cast<int64_t>(rows), dim}, torch::kHalf)
      .to(torch::kFloat);
}

class TorchQueryTrainerEngine final : public QueryTrainerEngine {
 public:
  TorchQueryTrainerEngine(const QueryMatrix& unit_rows, const TrainerOptions& options) : options_(options) {
    torch::manual_seed(options.seed);
    queries_ = torch::from_blob(const_cast<float*>(unit_rows.data()), {unit_rows.rows(), unit_rows.cols()},
                                torch::kFloat)
                   .clone()
                   .set_requires_grad(true);
    adam_ = std::make_unique<torch::optim::Adam>(std::vector<torch::Tensor>{queries_},
                                                 torch::optim::AdamOptions(options.learning_rate));
  }

  double train_epoch(const PixelSamples& samples, std::span<const std::size_t> order,
                     const StepProgress& progress) override {
    const int64_t dim = queries_.size(1);
    SingleThreadedTorch one_thread;
    const std::size_t batch = static_cast<std::size_t>(options_.batch_size);
    const std::size_t steps = (order.size() + batch - 1) / batch;
    std::vector<uint16_t> x(batch * dim);
    std::vector<int64_t> y(batch);
    double total = 0;
    for (std::size_t s = 0; s < steps; ++s) {
      const std::size_t first = s * batch, b = std::min(batch, order.size() - first);
      const std::span<const std::size_t> rows = order.subspan(first, b);
      samples.gather_half(rows, x.data());
      for (std::size_t i = 0; i < b; ++i) y[i] = samples.targets()[rows[i]];
      const auto xt = half_rows(x.data(), b, dim);
      const auto yt = torch::from_blob(y.data(), {static_cast<int64_t>(b)}, torch::kLong);
      const torch::Tensor loss = F::cross_entropy(logits(xt), yt);
      adam_->zero_grad();
      loss.backward();
      adam_->step();
      total += loss.item<double>() * static_cast<double>(b);
      if (progress) progress(s + 1, steps);
    }
    return total / static_cast<double>(order.size());
  }

  double loss(const PixelSamples& samples) const override {
    const int64_t dim = queries_.size(1);
    SingleThreadedTorch one_thread;
    torch::NoGradGuard no_grad;
    constexpr std::size_t kChunk = 8192;
    std::vector<int64_t> y(kChunk);
    double total = 0;
    for (std::size_t first = 0; first < samples.size(); first += kChunk) {
      const std::size_t b = std::min(kChunk, samples.size() - first);
      for (std::size_t i = 0; i < b; ++i) y[i] = samples.targets()[first + i];
      const auto xt = half_rows(samples.half_data() + first * dim, b, dim);
      const auto yt = torch::from_blob(y.data(), {static_cast<int64_t>(b)}, torch::kLong);
      total += F::cross_entropy(logits(xt), yt, F::CrossEntropyFuncOptions().reduction(torch::kSum)).item<double>();
    }
    return total / static_cast<double>(samples.size());
  }

  QueryMatrix queries() const override {
    torch::NoGradGuard no_grad;
    const torch::Tensor unit = F::normalize(queries_, F::NormalizeFuncOptions().p(2).dim(1)).contiguous();
    QueryMatrix out(unit.size(0), unit.size(1));
    std::copy(unit.data_ptr<float>(), unit.data_ptr<float>() + unit.numel(), out.data());
    return out;
  }

 private:
  torch::Tensor logits(const torch::Tensor& x) const {
    return x.matmul(F::normalize(queries_, F::NormalizeFuncOptions().p(2).dim(1)).t()) / options_.temperature;
  }

  TrainerOptions options_;
  torch::Tensor queries_;  // n x dim, the parameter
  std::unique_ptr<torch::optim::Adam> adam_;
};

std::unique_ptr<QueryTrainerEngine> make_engine(const QueryMatrix& unit_rows, const TrainerOptions& options) {
  return std::make_unique<TorchQueryTrainerEngine>(unit_rows, options);
}

}  // namespace
}  // namespace slamvdb

extern "C" __attribute__((visibility("default"))) const slamvdb::QueryTrainerFactory* slamvdb_query_trainer_factory() {
  static const slamvdb::QueryTrainerFactory factory{slamvdb::kQueryTrainerVersion, &slamvdb::make_engine};
  return &factory;
}
