#include "slamvdb/inference/torch_encoders.hpp"

#include <ATen/Parallel.h>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <torch/csrc/jit/runtime/graph_executor.h>
#include <torch/script.h>

#include <algorithm>

#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/clip_tokenizer.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;

// libtorch messages carry C++ backtraces and TorchScript tracebacks; the first line and the last
// line (the exception raised inside the model) are what a user can act on.
std::string brief(const std::exception& e) {
  const auto* c10 = dynamic_cast<const c10::Error*>(&e);
  std::string text = c10 ? c10->what_without_backtrace() : e.what();
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ')) text.pop_back();
  const auto first_end = text.find('\n');
  if (first_end == std::string::npos) return text;
  return text.substr(0, first_end) + " ... " + text.substr(text.rfind('\n') + 1);
}

std::string describe(const std::vector<ImageFrame>& frames, std::size_t first, std::size_t n) {
  const auto name = [](const ImageFrame& f) { return f.source.empty() ? std::string("<unnamed>") : f.source; };
  if (n == 1) return fmt::format("image '{}'", name(frames[first]));
  return fmt::format("a batch of {} images starting with '{}'", n, name(frames[first]));
}

at::Tensor unit_vectors(const at::Tensor& t, int64_t dim) {
  if (t.scalar_type() != torch::kHalf) return t / t.norm(2, dim, true).clamp_min(1e-12);
  // fp16 output stays fp16: the norms are taken in fp32 and the scale, capped to fp16's largest
  // value (a zero vector stays zero instead of 0 x inf), applied in fp16.
  const at::Tensor scale = t.norm(2, dim, true, torch::kFloat).clamp_min(1e-12).reciprocal().clamp_max(65504.0);
  return t * scale.to(torch::kHalf);
}

}  // namespace

// A loaded TorchScript module with its manifest; shared by the three encoders. In a named
// namespace: the encoders' Impl structs hold one, and a member of a type with internal linkage
// is a warning (-Wsubobject-linkage) when a unity build includes this file.
namespace torch_encoders_detail {

class TorchModel {
 public:
  TorchModel(const fs::path& model_or_manifest, ModelKind kind, const TorchEncoderOptions& options)
      : manifest_(load_model_manifest(model_or_manifest)) {
    if (manifest_.kind != kind) {
      throw Error(fmt::format("model manifest {} describes a {} model, but a {} encoder was asked for",
                              manifest_.manifest_path.string(), to_string(manifest_.kind), to_string(kind)));
    }
    if (!fs::is_regular_file(manifest_.model_path)) {
      throw Error(fmt::format("model file {} (described by {}) does not exist", manifest_.model_path.string(),
                              manifest_.manifest_path.string()));
    }
    threads_ = options.threads >= 0 ? options.threads : manifest_.threads;
    // The optimising executor profiles the first pass, recompiles on the second and again for
    // every new input shape: each a slow frame, with no speed-up for these conv / matmul graphs.
    torch::jit::setGraphExecutorOptimize(false);
    try {
      module_ = torch::jit::load(manifest_.model_path.string(), torch::kCPU);
    } catch (const std::exception& e) {
      throw Error(fmt::format("cannot load TorchScript model {}: {}", manifest_.model_path.string(), brief(e)));
    }
    module_.eval();
  }

  const ModelManifest& manifest() const { return manifest_; }

  // Runs the network on `input` and returns its output, contiguous, as fp32 or (keep_half and the
  // network gives fp16) as fp16; `what` names the input in errors.
  at::Tensor forward(at::Tensor input, const std::string& what, bool keep_half = false) {
    if (threads_ > 0) at::set_num_threads(threads_);
    c10::InferenceMode no_autograd;
    c10::IValue out;
    try {
      out = module_.forward({std::move(input)});
    } catch (const std::exception& e) {
      throw Error(fmt::format("model '{}' ({}) failed on {}: {}", manifest_.model_id, manifest_.model_path.string(),
                              what, brief(e)));
    }
    if (!out.isTensor()) {
      throw Error(fmt::format("model '{}' ({}) returned a {} instead of a tensor", manifest_.model_id,
                              manifest_.model_path.string(), out.tagKind()));
    }
    at::Tensor t = out.toTensor();
    if (keep_half && t.scalar_type() == torch::kHalf) return t.contiguous();
    return t.to(torch::kFloat).contiguous();
  }

  void expect_shape(const at::Tensor& t, const std::vector<int64_t>& expected, const char* fields,
                    const std::string& what) const {
    if (t.sizes().vec() != expected) {
      throw Error(fmt::format("model '{}' ({}) output for {} has shape [{}] but manifest {} says [{}] ({})",
                              manifest_.model_id, manifest_.model_path.string(), what, fmt::join(t.sizes(), ", "),
                              manifest_.manifest_path.string(), fmt::join(expected, ", "), fields));
    }
  }

  // The manifest's output.l2_normalized promise, checked on the warm-up output (vectors along `dim`).
  void expect_unit_vectors(const at::Tensor& t, int64_t dim) const {
    if (!manifest_.output.l2_normalized) return;
    const at::Tensor norms = t.norm(2, dim);
    const float lo = norms.min().item<float>(), hi = norms.max().item<float>();
    if (lo < 0.99f || hi > 1.01f) {
      throw Error(
          fmt::format("manifest {} says output.l2_normalized = true, but model '{}' outputs vectors with "
                      "norms in [{:.4g}, {:.4g}]",
                      manifest_.manifest_path.string(), manifest_.model_id, lo, hi));
    }
  }

  // N pre-processed frames as an N x 3 x H x W tensor.
  at::Tensor image_batch(const std::vector<ImageFrame>& frames, std::size_t first, std::size_t n) const {
    const auto& in = manifest_.input;
    at::Tensor batch = torch::empty({static_cast<int64_t>(n), 3, in.height, in.width}, torch::kFloat);
    const std::size_t stride = std::size_t{3} * in.height * in.width;
    for (std::size_t i = 0; i < n; ++i) {
      image_to_network_input(frames[first + i], manifest_, batch.data_ptr<float>() + i * stride);
    }
    return batch;
  }

  ImageFrame warm_up_frame() const {
    ImageFrame frame;
    frame.rgb = cv::Mat(manifest_.input.height, manifest_.input.width, CV_8UC3, cv::Scalar(128, 128, 128));
    frame.source = "warm-up image";
    return frame;
  }

 private:
  ModelManifest manifest_;
  torch::jit::Module module_;
  int threads_ = 0;
};

}  // namespace torch_encoders_detail
using torch_encoders_detail::TorchModel;

// ------------------------------------------------------------------------------------------ dense
struct TorchDenseImageEncoder::Impl {
  TorchModel model;

  std::vector<FeatureMap> encode_batch(const std::vector<ImageFrame>& frames) {
    const ModelManifest& m = model.manifest();
    const OutputSpec& o = m.output;
    std::vector<FeatureMap> maps;
    maps.reserve(frames.size());
    for (std::size_t first = 0; first < frames.size(); first += m.batch_size) {
      const std::size_t n = std::min<std::size_t>(m.batch_size, frames.size() - first);
      const std::string what = describe(frames, first, n);
      at::Tensor out = model.forward(model.image_batch(frames, first, n), what, /*keep_half=*/true);
      model.expect_shape(out, {static_cast<int64_t>(n), o.dim, o.height, o.width},
                         "N x output.dim x output.height x output.width", what);
      if (o.normalize_output) out = unit_vectors(out, 1);
      // C x h x w -> pixel-major, straight into the map. As a 2-D transpose, ATen's blocked copy
      // is ~4x faster than a permuted 3-D copy (70 -> 16 ms for 512 x 128 x 192). An fp16 output
      // (a network run in half precision) stays fp16: fusion reads half the bytes.
      const int64_t pixels = int64_t{o.height} * o.width;
      const bool half = out.scalar_type() == torch::kHalf;
      for (std::size_t i = 0; i < n; ++i) {
        FeatureMap& map = maps.emplace_back(o.dim, o.height, o.width,
                                            half ? EmbeddingPrecision::kFloat16 : EmbeddingPrecision::kFloat32);
        void* storage = half ? static_cast<void*>(map.half_values().data()) : map.values().data();
        torch::from_blob(storage, {pixels, o.dim}, half ? torch::kHalf : torch::kFloat)
            .copy_(out[static_cast<int64_t>(i)].view({o.dim, pixels}).t());
      }
    }
    return maps;
  }
};

TorchDenseImageEncoder::TorchDenseImageEncoder(const fs::path& model_or_manifest, const TorchEncoderOptions& options)
    : impl_(new Impl{TorchModel(model_or_manifest, ModelKind::kDenseImage, options)}) {  // clang 14: no parenthesized aggregate init
  if (!options.warm_up) return;
  const FeatureMap map =
      impl_->encode_batch({impl_->model.warm_up_frame()}).front().converted(EmbeddingPrecision::kFloat32);
  impl_->model.expect_unit_vectors(
      torch::from_blob(const_cast<float*>(map.values().data()), {static_cast<int64_t>(map.pixels()), map.dim()}), 1);
}
TorchDenseImageEncoder::~TorchDenseImageEncoder() = default;
FeatureMap TorchDenseImageEncoder::encode(const ImageFrame& frame) {
  return std::move(impl_->encode_batch({frame}).front());
}
std::vector<FeatureMap> TorchDenseImageEncoder::encode_batch(const std::vector<ImageFrame>& frames) {
  return impl_->encode_batch(frames);
}
int TorchDenseImageEncoder::dim() const { return impl_->model.manifest().output.dim; }
std::string TorchDenseImageEncoder::model_id() const { return impl_->model.manifest().model_id; }
const ModelManifest& TorchDenseImageEncoder::manifest() const { return impl_->model.manifest(); }

// ------------------------------------------------------------------------------------------ image
struct TorchImageEncoder::Impl {
  TorchModel model;

  std::vector<float> encode(const ImageFrame& frame) {
    const OutputSpec& o = model.manifest().output;
    const std::vector<ImageFrame> frames{frame};
    const std::string what = describe(frames, 0, 1);
    at::Tensor out = model.forward(model.image_batch(frames, 0, 1), what);
    model.expect_shape(out, {1, o.dim}, "1 x output.dim", what);
    if (o.normalize_output) out = unit_vectors(out, 1);
    return {out.data_ptr<float>(), out.data_ptr<float>() + o.dim};
  }
};

TorchImageEncoder::TorchImageEncoder(const fs::path& model_or_manifest, const TorchEncoderOptions& options)
    : impl_(new Impl{TorchModel(model_or_manifest, ModelKind::kImage, options)}) {
  if (!options.warm_up) return;
  std::vector<float> v = impl_->encode(impl_->model.warm_up_frame());
  impl_->model.expect_unit_vectors(torch::from_blob(v.data(), {1, static_cast<int64_t>(v.size())}), 1);
}
TorchImageEncoder::~TorchImageEncoder() = default;
std::vector<float> TorchImageEncoder::encode(const ImageFrame& frame) { return impl_->encode(frame); }
int TorchImageEncoder::dim() const { return impl_->model.manifest().output.dim; }
std::string TorchImageEncoder::model_id() const { return impl_->model.manifest().model_id; }
const ModelManifest& TorchImageEncoder::manifest() const { return impl_->model.manifest(); }

// ------------------------------------------------------------------------------------------- text
struct TorchTextEncoder::Impl {
  TorchModel model;
  ClipTokenizer tokenizer;

  static ClipTokenizer open_vocab(const ModelManifest& m) {
    if (!fs::is_regular_file(m.text.vocab)) {
      throw Error(fmt::format("CLIP vocabulary {} (text.vocab of manifest {}) does not exist", m.text.vocab.string(),
                              m.manifest_path.string()));
    }
    return ClipTokenizer(m.text.vocab);
  }

  explicit Impl(TorchModel&& m) : model(std::move(m)), tokenizer(open_vocab(model.manifest())) {}

  std::vector<float> encode(std::string_view text) {
    const ModelManifest& m = model.manifest();
    std::vector<int64_t> tokens = tokenizer.tokenize(text, m.text.context_length, /*truncate=*/true);
    const std::string what = fmt::format("text \"{}\"", text);
    at::Tensor input = torch::from_blob(tokens.data(), {1, static_cast<int64_t>(tokens.size())}, torch::kLong).clone();
    at::Tensor out = model.forward(input, what);
    model.expect_shape(out, {1, m.output.dim}, "1 x output.dim", what);
    if (m.output.normalize_output) out = unit_vectors(out, 1);
    return {out.data_ptr<float>(), out.data_ptr<float>() + m.output.dim};
  }
};

TorchTextEncoder::TorchTextEncoder(const fs::path& model_or_manifest, const TorchEncoderOptions& options)
    : impl_(std::make_unique<Impl>(TorchModel(model_or_manifest, ModelKind::kText, options))) {
  if (!options.warm_up) return;
  std::vector<float> v = impl_->encode("a photo of a tree");
  impl_->model.expect_unit_vectors(torch::from_blob(v.data(), {1, static_cast<int64_t>(v.size())}), 1);
}
TorchTextEncoder::~TorchTextEncoder() = default;
std::vector<float> TorchTextEncoder::encode(std::string_view text) { return impl_->encode(text); }
int TorchTextEncoder::dim() const { return impl_->model.manifest().output.dim; }
std::string TorchTextEncoder::model_id() const { return impl_->model.manifest().model_id; }
const ModelManifest& TorchTextEncoder::manifest() const { return impl_->model.manifest(); }

}  // namespace slamvdb
