#include "slamvdb/inference/simulated_encoders.hpp"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstring>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/ontology.hpp"

namespace slamvdb {
namespace {

// splitmix64: a portable generator, so the simulation gives the same features on every platform
// (std::normal_distribution is implementation-defined).
uint64_t mix(uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}
uint64_t mix(uint64_t a, uint64_t b) { return mix(a ^ mix(b)); }

struct Rng {
  uint64_t state;
  uint64_t next() { return state = mix(state); }
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  float gaussian() {  // Box-Muller
    const double u = 1.0 - uniform(), v = uniform();
    return static_cast<float>(std::sqrt(-2.0 * std::log(u)) * std::cos(2.0 * std::numbers::pi * v));
  }
};

Eigen::VectorXf random_unit_vector(uint64_t seed, int dim) {
  Rng rng{seed};
  Eigen::VectorXf v(dim);
  for (int i = 0; i < dim; ++i) v[i] = rng.gaussian();
  return v.normalized();
}

uint64_t stamp_bits(double stamp) {
  uint64_t bits;
  std::memcpy(&bits, &stamp, sizeof bits);
  return bits;
}

std::string ids_of_classes() {
  std::string names;
  for (const auto& c : rellis_classes()) names += fmt::format("{}{}", names.empty() ? "" : ", ", c.id);
  return names;
}

}  // namespace

void validate(const SimulatedEncoderConfig& c) {
  const auto fail = [](const std::string& what) { throw Error("simulated encoder config: " + what); };
  if (c.dim < 1) fail(fmt::format("dim must be >= 1, got {}", c.dim));
  if (c.height < 1 || c.width < 1) fail(fmt::format("feature size must be >= 1 x 1, got {} x {}", c.height, c.width));
  if (!(c.related_cosine >= 0.f && c.related_cosine < 1.f))
    fail(fmt::format("related_cosine must be in [0, 1), got {}", c.related_cosine));
  if (!(c.confusion_rate >= 0.f && c.confusion_rate <= 1.f))
    fail(fmt::format("confusion_rate must be in [0, 1], got {}", c.confusion_rate));
  if (c.confusion_cell < 1) fail(fmt::format("confusion_cell must be >= 1, got {}", c.confusion_cell));
  if (!(c.related_confusion >= 0.f && c.related_confusion <= 1.f))
    fail(fmt::format("related_confusion must be in [0, 1], got {}", c.related_confusion));
  if (!(c.noise_sigma >= 0.f) || !std::isfinite(c.noise_sigma))
    fail(fmt::format("noise_sigma must be >= 0, got {}", c.noise_sigma));
  if (!(c.blur >= 0.f) || !std::isfinite(c.blur)) fail(fmt::format("blur must be >= 0, got {}", c.blur));
  if (!(c.text_gap >= 0.f) || !std::isfinite(c.text_gap))
    fail(fmt::format("text_gap must be >= 0, got {}", c.text_gap));
}

PrototypeMatrix simulated_class_prototypes(const SimulatedEncoderConfig& config) {
  validate(config);
  const auto& classes = rellis_classes();
  const float a = std::sqrt(config.related_cosine), b = std::sqrt(1.f - config.related_cosine);
  PrototypeMatrix prototypes(classes.size(), config.dim);
  for (std::size_t i = 0; i < classes.size(); ++i) {
    // Keyed by coarse index and class id, so a class's prototype does not depend on list order.
    const Eigen::VectorXf coarse = random_unit_vector(mix(config.seed, 0xC0A45E00u + classes[i].coarse), config.dim);
    const Eigen::VectorXf own = random_unit_vector(mix(config.seed, 0xF14E0000u + classes[i].id), config.dim);
    prototypes.row(i) = (a * coarse + b * own).normalized().transpose();
  }
  return prototypes;
}

std::string simulated_model_id(const SimulatedEncoderConfig& config) {
  return fmt::format("simulated-lseg-v1(seed={},dim={},related={:.2f})", config.seed, config.dim,
                     config.related_cosine);
}

SimulatedDenseEncoder::SimulatedDenseEncoder(SimulatedEncoderConfig config)
    : config_(config), prototypes_(simulated_class_prototypes(config)) {
  class_row_.fill(-1);
  const auto& classes = rellis_classes();
  for (std::size_t i = 0; i < classes.size(); ++i) class_row_[classes[i].id] = static_cast<int>(i);

  // Drawing a Gaussian per value per frame would dominate the cost; pixels pick rows of a bank.
  const float component_sigma = 1.f / std::sqrt(static_cast<float>(config_.dim));
  noise_bank_.resize(static_cast<std::size_t>(kNoiseBankSize) * config_.dim);
  Rng rng{mix(config_.seed, 0x401538A4u)};
  for (float& v : noise_bank_) v = component_sigma * rng.gaussian();
}

FeatureMap SimulatedDenseEncoder::encode(const ImageFrame& frame) {
  FeatureMap out;
  encode_into(frame, out);
  return out;
}

void SimulatedDenseEncoder::encode_into(const ImageFrame& frame, FeatureMap& out) {
  const std::string where = fmt::format("frame '{}' (stamp {:.6f})", frame.source, frame.stamp);
  if (frame.labels.empty())
    throw Error(where + " has no 2D label image: the simulated dense encoder reads labels, not pixels");
  if (frame.labels.type() != CV_8UC1)
    throw Error(where + " label image is not 8-bit single-channel (RELLIS-3D ids)");
  for (int y = 0; y < frame.labels.rows; ++y) {
    const uint8_t* row = frame.labels.ptr<uint8_t>(y);
    for (int x = 0; x < frame.labels.cols; ++x)
      if (class_row_[row[x]] < 0)
        throw Error(fmt::format("{} label {} at pixel ({}, {}) is no RELLIS-3D class (known ids: {})", where, row[x],
                                x, y, ids_of_classes()));
  }

  const int H = config_.height, W = config_.width, D = config_.dim, K = static_cast<int>(prototypes_.rows());
  cv::Mat labels;
  cv::resize(frame.labels, labels, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);

  // Confusion: cells of a grid whose offset changes per view; in a swapped cell every class
  // becomes another one, a related class (same coarse class) preferred.
  const uint64_t view = mix(config_.seed, stamp_bits(frame.stamp));
  Rng view_rng{view};
  const int cell = config_.confusion_cell;
  const int offset_x = static_cast<int>(view_rng.next() % cell), offset_y = static_cast<int>(view_rng.next() % cell);
  const int cells_x = (W + offset_x + cell - 1) / cell, cells_y = (H + offset_y + cell - 1) / cell;
  const auto& classes = rellis_classes();
  std::vector<std::vector<int>> related(K);
  for (int k = 0; k < K; ++k)
    for (int j = 0; j < K; ++j)
      if (j != k && classes[j].coarse == classes[k].coarse) related[k].push_back(j);
  std::vector<int> cell_map(static_cast<std::size_t>(cells_x) * cells_y * K);  // cell, class -> class
  for (int c = 0; c < cells_x * cells_y; ++c) {
    Rng rng{mix(view, static_cast<uint64_t>(c))};
    const bool swapped = rng.uniform() < config_.confusion_rate;
    for (int k = 0; k < K; ++k) {
      int to = k;
      if (swapped) {
        if (!related[k].empty() && rng.uniform() < config_.related_confusion) {
          to = related[k][rng.next() % related[k].size()];
        } else {
          to = static_cast<int>(rng.next() % (K - 1));
          to += to >= k;  // any class but k
        }
      }
      cell_map[static_cast<std::size_t>(c) * K + k] = to;
    }
  }
  std::vector<int> seen(static_cast<std::size_t>(H) * W);
  std::vector<bool> present(K, false);
  for (int y = 0; y < H; ++y) {
    const uint8_t* row = labels.ptr<uint8_t>(y);
    for (int x = 0; x < W; ++x) {
      const int c = (y + offset_y) / cell * cells_x + (x + offset_x) / cell;
      const int k = cell_map[static_cast<std::size_t>(c) * K + class_row_[row[x]]];
      seen[static_cast<std::size_t>(y) * W + x] = k;
      present[k] = true;
    }
  }

  // Low resolution: each present class's indicator, blurred, weights its prototype.
  std::vector<int> rows;
  std::vector<cv::Mat> weights;
  for (int k = 0; k < K; ++k) {
    if (!present[k]) continue;
    cv::Mat indicator(H, W, CV_32F);
    float* value = indicator.ptr<float>();
    for (std::size_t i = 0; i < seen.size(); ++i) value[i] = seen[i] == k ? 1.f : 0.f;
    if (config_.blur > 0.f) cv::GaussianBlur(indicator, indicator, cv::Size(0, 0), config_.blur);
    rows.push_back(k);
    weights.push_back(std::move(indicator));
  }

  // One pass per pixel: the (mostly single) weighted prototype plus a bank row, cyclically shifted
  // and signed per pixel (a shifted row of iid Gaussians is again one), then normalised.
  const bool half = config_.output_precision == EmbeddingPrecision::kFloat16;
  out.reset(D, H, W, config_.output_precision);  // every value is written below
  tbb::parallel_for(0, H, [&](int y) {
    std::vector<float> row_scratch(half ? static_cast<std::size_t>(D) : 0);  // fp32 pixel before rounding
    for (int x = 0; x < W; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      const uint64_t h = mix(view, 0x5EED0000000ull + i);
      const float* noise = noise_bank_.data() + (h % kNoiseBankSize) * D;
      const int shift = static_cast<int>((h >> 16) % D);
      const float sigma = (h >> 63) ? -config_.noise_sigma : config_.noise_sigma;
      Eigen::Map<Eigen::VectorXf> f(half ? row_scratch.data() : out.pixel(x, y), D);
      f.head(D - shift) = sigma * Eigen::Map<const Eigen::VectorXf>(noise + shift, D - shift);
      f.tail(shift) = sigma * Eigen::Map<const Eigen::VectorXf>(noise, shift);
      for (std::size_t r = 0; r < rows.size(); ++r) {
        const float w = weights[r].ptr<float>()[i];
        if (w > 1e-4f) f += w * prototypes_.row(rows[r]).transpose();
      }
      const float norm = f.norm();
      if (norm > 0.f) f *= 1.f / norm;
      if (half) kernels::float_to_half(f.data(), out.half_pixel(x, y), static_cast<std::size_t>(D));
    }
  });
}

SimulatedTextEncoder::SimulatedTextEncoder(SimulatedEncoderConfig config) : config_(config) {
  const PrototypeMatrix prototypes = simulated_class_prototypes(config_);
  const auto& classes = rellis_classes();
  // The text-image gap: ideal + gap * a mix of the prototypes of classes outside `members`, with
  // weights u^4 (u uniform) so that each name leans on a few other classes. Keyed by `key`.
  const auto with_gap = [&](Eigen::VectorXf ideal, const std::vector<bool>& members, uint64_t key) {
    if (config_.text_gap <= 0.f) return ideal;
    Rng rng{mix(config_.seed, 0x7E47'0000'0000ull + key)};
    Eigen::VectorXf others = Eigen::VectorXf::Zero(config_.dim);
    double total = 0;
    for (std::size_t j = 0; j < classes.size(); ++j) {
      const double u = rng.uniform(), w = u * u * u * u;
      if (members[j]) continue;
      others += static_cast<float>(w) * prototypes.row(j).transpose();
      total += w;
    }
    if (total > 0) ideal += (config_.text_gap / static_cast<float>(total)) * others;
    return Eigen::VectorXf(ideal.normalized());
  };
  for (std::size_t i = 0; i < classes.size(); ++i) {
    std::vector<bool> members(classes.size(), false);
    members[i] = true;
    names_.emplace_back(std::string(classes[i].name), with_gap(prototypes.row(i).transpose(), members, classes[i].id));
  }
  for (int k = 0; k < static_cast<int>(kCoarseClasses.size()); ++k) {
    if (k == kVoidCoarse) continue;  // "void" names the fine class
    Eigen::VectorXf sum = Eigen::VectorXf::Zero(config_.dim);
    std::vector<bool> members(classes.size(), false);
    for (std::size_t i = 0; i < classes.size(); ++i)
      if (classes[i].coarse == k) sum += prototypes.row(i).transpose(), members[i] = true;
    names_.emplace_back(std::string(kCoarseClasses[k]), with_gap(sum.normalized(), members, 0x10000u + k));
  }
}

std::vector<float> SimulatedTextEncoder::encode(std::string_view text) {
  const auto find = [&](std::string_view word) -> const Eigen::VectorXf* {
    for (const auto& [name, vector] : names_)
      if (name == word) return &vector;
    return nullptr;
  };
  Eigen::VectorXf sum = Eigen::VectorXf::Zero(config_.dim);
  std::vector<const Eigen::VectorXf*> used;
  std::string word;
  for (std::size_t i = 0; i <= text.size(); ++i) {
    const char c = i < text.size() ? text[i] : ' ';
    if (std::isalnum(static_cast<unsigned char>(c))) {
      word.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
      continue;
    }
    if (word.empty()) continue;
    const Eigen::VectorXf* v = find(word);
    if (!v && word.ends_with("es")) v = find(std::string_view(word).substr(0, word.size() - 2));  // bushes
    if (!v && word.ends_with('s')) v = find(std::string_view(word).substr(0, word.size() - 1));   // trees
    if (v && std::find(used.begin(), used.end(), v) == used.end()) {
      used.push_back(v);
      sum += *v;
    }
    word.clear();
  }
  if (used.empty()) {
    std::string known;
    for (const auto& [name, vector] : names_) known += (known.empty() ? "" : ", ") + name;
    throw Error("the simulated text encoder knows no class in '" + std::string(text) + "'; it knows: " + known);
  }
  sum.normalize();
  return std::vector<float>(sum.data(), sum.data() + sum.size());
}

std::vector<float> SimulatedImageEncoder::encode(const ImageFrame& frame) {
  const FeatureMap features = dense_.encode(frame);
  Eigen::VectorXd sum = Eigen::VectorXd::Zero(features.dim());
  Eigen::VectorXf pixel(features.dim());
  for (int y = 0; y < features.height(); ++y)
    for (int x = 0; x < features.width(); ++x) {
      features.decode_pixel(x, y, pixel.data());
      sum += pixel.cast<double>();
    }
  const Eigen::VectorXf mean = sum.normalized().cast<float>();
  return std::vector<float>(mean.data(), mean.data() + mean.size());
}

}  // namespace slamvdb
