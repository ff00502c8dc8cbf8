#include "slamvdb/training/query_trainer.hpp"
#include "slamvdb/core/mix64.hpp"

#include <fmt/format.h>
#include <torch/torch.h>

#include <algorithm>
#include <cmath>
#include <numeric>

#include "slamvdb/core/error.hpp"

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

void check_targets(const PixelSamples& samples, int classes) {
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

struct QueryTrainer::Impl {
  TrainerOptions options;
  torch::Tensor queries;  // n x dim, the parameter
  std::unique_ptr<torch::optim::Adam> adam;
  int epoch = 0;

  torch::Tensor logits(const torch::Tensor& x) const {
    return x.matmul(F::normalize(queries, F::NormalizeFuncOptions().p(2).dim(1)).t()) / options.temperature;
  }
};

QueryTrainer::QueryTrainer(const QueryMatrix& initial, const TrainerOptions& options) : impl_(std::make_unique<Impl>()) {
  validate(options);
  if (initial.rows() < 1 || initial.cols() < 1) throw Error("query training needs at least one class and dimension");
  // Unit rows with the norm in double (query_set.hpp: no float overflow or underflow).
  QueryMatrix unit(initial.rows(), initial.cols());
  for (Eigen::Index k = 0; k < initial.rows(); ++k) {
    const auto row = unit_vector({initial.row(k).data(), static_cast<std::size_t>(initial.cols())});
    if (!row) throw Error(fmt::format("initial query {} is zero or not finite", k));
    unit.row(k) = row->transpose();
  }
  torch::manual_seed(options.seed);
  impl_->options = options;
  impl_->queries = torch::from_blob(const_cast<float*>(unit.data()), {unit.rows(), unit.cols()}, torch::kFloat)
                       .clone()
                       .set_requires_grad(true);
  impl_->adam = std::make_unique<torch::optim::Adam>(std::vector<torch::Tensor>{impl_->queries},
                                                     torch::optim::AdamOptions(options.learning_rate));
}

QueryTrainer::~QueryTrainer() = default;

double QueryTrainer::train_epoch(const PixelSamples& samples, const StepProgress& progress) {
  const int64_t n = impl_->queries.size(0), dim = impl_->queries.size(1);
  if (samples.dim() != dim) throw Error(fmt::format("{}-d samples for {}-d queries", samples.dim(), dim));
  if (samples.size() == 0) throw Error("no training pixels");
  check_targets(samples, static_cast<int>(n));
  SingleThreadedTorch one_thread;

  std::vector<std::size_t> order(samples.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  uint64_t state = mix64(impl_->options.seed ^ mix64(0xE90C0000u + static_cast<uint64_t>(impl_->epoch)));
  for (std::size_t i = order.size(); i > 1; --i) {  // Fisher-Yates with a portable generator
    state = mix64(state);
    std::swap(order[i - 1], order[state % i]);
  }
  const std::size_t batch = static_cast<std::size_t>(impl_->options.batch_size);
  const std::size_t steps = (samples.size() + batch - 1) / batch;
  std::vector<uint16_t> x(batch * dim);
  std::vector<int64_t> y(batch);
  double total = 0;
  for (std::size_t s = 0; s < steps; ++s) {
    const std::size_t first = s * batch, b = std::min(batch, samples.size() - first);
    const std::span<const std::size_t> rows(order.data() + first, b);
    samples.gather_half(rows, x.data());
    for (std::size_t i = 0; i < b; ++i) y[i] = samples.targets()[rows[i]];
    const auto xt = half_rows(x.data(), b, dim);
    const auto yt = torch::from_blob(y.data(), {static_cast<int64_t>(b)}, torch::kLong);
    const torch::Tensor loss = F::cross_entropy(impl_->logits(xt), yt);
    impl_->adam->zero_grad();
    loss.backward();
    impl_->adam->step();
    total += loss.item<double>() * static_cast<double>(b);
    if (progress) progress(s + 1, steps);
  }
  ++impl_->epoch;
  return total / static_cast<double>(samples.size());
}

double QueryTrainer::loss(const PixelSamples& samples) const {
  const int64_t n = impl_->queries.size(0), dim = impl_->queries.size(1);
  if (samples.dim() != dim) throw Error(fmt::format("{}-d samples for {}-d queries", samples.dim(), dim));
  if (samples.size() == 0) return 0.0;
  check_targets(samples, static_cast<int>(n));
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
    total += F::cross_entropy(impl_->logits(xt), yt, F::CrossEntropyFuncOptions().reduction(torch::kSum)).item<double>();
  }
  return total / static_cast<double>(samples.size());
}

QueryMatrix QueryTrainer::queries() const {
  torch::NoGradGuard no_grad;
  const torch::Tensor unit = F::normalize(impl_->queries, F::NormalizeFuncOptions().p(2).dim(1)).contiguous();
  QueryMatrix out(unit.size(0), unit.size(1));
  std::copy(unit.data_ptr<float>(), unit.data_ptr<float>() + unit.numel(), out.data());
  return out;
}

int QueryTrainer::epochs_done() const { return impl_->epoch; }

}  // namespace slamvdb
