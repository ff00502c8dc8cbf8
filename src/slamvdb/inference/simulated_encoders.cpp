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
#include "slamvdb/inference/simulated_failures.hpp"

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

// The class an erring pixel of class row k shows: a look-alike with probability lookalike_share
// (when it has any), else a related class with probability related_share (when it has any), else
// any class but k. Draws from rng only for the choices it makes.
int pick_wrong_class(int k, int num_classes, const std::vector<int>& lookalikes, float lookalike_share,
                     const std::vector<int>& related, float related_share, Rng& rng) {
  if (!lookalikes.empty() && rng.uniform() < lookalike_share) return lookalikes[rng.next() % lookalikes.size()];
  if (!related.empty() && rng.uniform() < related_share) return related[rng.next() % related.size()];
  const int to = static_cast<int>(rng.next() % (num_classes - 1));
  return to + (to >= k);  // any class but k
}

std::string ids_of_classes() {
  std::string names;
  for (const auto& c : rellis_classes()) names += fmt::format("{}{}", names.empty() ? "" : ", ", c.id);
  return names;
}

}  // namespace

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
  const int K = static_cast<int>(classes.size());
  related_.resize(K);
  lookalike_.resize(K);
  for (int k = 0; k < K; ++k) {
    for (int j = 0; j < K; ++j)
      if (j != k && classes[j].coarse == classes[k].coarse) related_[k].push_back(j);
    for (const uint16_t id : simulated_lookalikes(classes[k].id)) lookalike_[k].push_back(class_row_[id]);
  }

  // Drawing a Gaussian per value per frame would dominate the cost; pixels pick rows of a bank.
  const float component_sigma = 1.f / std::sqrt(static_cast<float>(config_.dim));
  noise_bank_.resize(static_cast<std::size_t>(kNoiseBankSize) * config_.dim);
  Rng rng{mix(config_.seed, 0x401538A4u)};
  for (float& v : noise_bank_) v = component_sigma * rng.gaussian();
}

int SimulatedDenseEncoder::wrong_class(int k, uint64_t key) const {
  Rng rng{key ^ static_cast<uint64_t>(k) * 0x9E3779B97F4A7C15ull};
  return pick_wrong_class(k, static_cast<int>(prototypes_.rows()), lookalike_[k], config_.lookalike_share, related_[k],
                          config_.related_confusion, rng);
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

  const int H = config_.height, W = config_.width, K = static_cast<int>(prototypes_.rows());
  cv::Mat labels;
  cv::resize(frame.labels, labels, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
  cv::Mat view;
  if (!frame.view.empty()) {
    if (frame.view.type() != CV_16UC3) throw Error(where + " view geometry image is not 16-bit with 3 channels");
    cv::resize(frame.view, view, cv::Size(W, H), 0, 0, cv::INTER_NEAREST);
  }
  const auto& classes = rellis_classes();
  const uint64_t view_key = mix(config_.seed, stamp_bits(frame.stamp));
  std::vector<int> seen(static_cast<std::size_t>(H) * W);
  for (int y = 0; y < H; ++y) {
    const uint8_t* row = labels.ptr<uint8_t>(y);
    for (int x = 0; x < W; ++x) seen[static_cast<std::size_t>(y) * W + x] = class_row_[row[x]];
  }

  // Where a real network errs (view, exposure, persistent look-alikes), and which class it shows.
  {
    std::vector<int> erring_rows(seen.size());
    for (std::size_t i = 0; i < seen.size(); ++i) erring_rows[i] = classes[seen[i]].coarse == kVoidCoarse ? -1 : seen[i];
    const sim_failures::PixelErrors errors = sim_failures::pixel_errors(config_, erring_rows, view, frame.stamp, view_key);
    for (std::size_t i = 0; i < seen.size(); ++i)
      if (errors.wrong[i])
        seen[i] = wrong_class(seen[i], mix(config_.seed, 0xC401CE00ull + static_cast<uint64_t>(std::floor(
                                                                              2.0 * errors.choice[i] + 1000.0))));
  }

  // Per-view blob swaps: cells of a grid whose offset changes per view; in a swapped cell every
  // class becomes another one, a related class (same coarse class) preferred.
  if (config_.confusion_rate > 0.f) {
    Rng view_rng{view_key};
    const int cell = config_.confusion_cell;
    const int offset_x = static_cast<int>(view_rng.next() % cell), offset_y = static_cast<int>(view_rng.next() % cell);
    const int cells_x = (W + offset_x + cell - 1) / cell, cells_y = (H + offset_y + cell - 1) / cell;
    std::vector<int> cell_map(static_cast<std::size_t>(cells_x) * cells_y * K);  // cell, class -> class
    for (int c = 0; c < cells_x * cells_y; ++c) {
      Rng rng{mix(view_key, static_cast<uint64_t>(c))};
      const bool swapped = rng.uniform() < config_.confusion_rate;
      for (int k = 0; k < K; ++k) {
        static const std::vector<int> kNoLookalikes;  // blob swaps show related or any classes
        cell_map[static_cast<std::size_t>(c) * K + k] =
            swapped ? pick_wrong_class(k, K, kNoLookalikes, 0.f, related_[k], config_.related_confusion, rng) : k;
      }
    }
    for (int y = 0; y < H; ++y)
      for (int x = 0; x < W; ++x) {
        int& k = seen[static_cast<std::size_t>(y) * W + x];
        k = cell_map[static_cast<std::size_t>((y + offset_y) / cell * cells_x + (x + offset_x) / cell) * K + k];
      }
  }
  std::vector<bool> present(K, false);
  for (const int k : seen) present[k] = true;

  // Low resolution: each present class's indicator averaged over the coarse grid, upsampled
  // bilinearly, blurred; it weights the class's prototype.
  const int f = config_.coarse_factor;
  const cv::Size coarse(std::max(1, (W + f - 1) / f), std::max(1, (H + f - 1) / f));
  std::vector<int> rows;
  std::vector<cv::Mat> weights;
  for (int k = 0; k < K; ++k) {
    if (!present[k]) continue;
    cv::Mat indicator(H, W, CV_32F);
    float* value = indicator.ptr<float>();
    for (std::size_t i = 0; i < seen.size(); ++i) value[i] = seen[i] == k ? 1.f : 0.f;
    if (f > 1) {
      cv::Mat small;
      cv::resize(indicator, small, coarse, 0, 0, cv::INTER_AREA);
      cv::resize(small, indicator, cv::Size(W, H), 0, 0, cv::INTER_LINEAR);
    }
    if (config_.blur > 0.f) cv::GaussianBlur(indicator, indicator, cv::Size(0, 0), config_.blur);
    rows.push_back(k);
    weights.push_back(std::move(indicator));
  }

  // One pass per pixel: the (mostly single) weighted prototype plus a bank row, cyclically shifted
  // and signed per pixel (a shifted row of iid Gaussians is again one), then normalised.
  const int D = config_.dim;
  const bool half = config_.output_precision == EmbeddingPrecision::kFloat16;
  out.reset(D, H, W, config_.output_precision);  // every value is written below
  tbb::parallel_for(0, H, [&](int y) {
    std::vector<float> row_scratch(half ? static_cast<std::size_t>(D) : 0);  // fp32 pixel before rounding
    for (int x = 0; x < W; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * W + x;
      const uint64_t h = mix(view_key, 0x5EED0000000ull + i);
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
