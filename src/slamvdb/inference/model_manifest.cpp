#include "slamvdb/inference/model_manifest.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <set>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

constexpr int kMaxSide = 16384;
constexpr int kMaxDim = 4096;      // embedding dimension (CLIP / LSeg: 512; the largest CLIPs 1280)
constexpr int kMaxThreads = 256;   // runtime.threads
constexpr double kMaxTensorBytes = double(1 << 30);  // one input batch or one image's output, float32

// Reads one JSON object of the manifest, remembering which keys were read so that anything left
// over (a typo, a field of another kind) is reported instead of silently ignored.
class Fields {
 public:
  Fields(const json& object, std::string prefix, const fs::path& file)
      : object_(object), prefix_(std::move(prefix)), file_(file) {}

  bool has(const std::string& key) const { return object_.contains(key); }

  const json& get(const std::string& key) {
    if (!object_.contains(key)) fail(key, "is missing");
    read_.insert(key);
    return object_.at(key);
  }
  int integer(const std::string& key, int min, int max) {
    const json& v = get(key);
    if (!v.is_number_integer() || v.get<long long>() < min || v.get<long long>() > max) {
      fail(key, fmt::format("must be an integer in [{}, {}], got {}", min, max, v.dump()));
    }
    return v.get<int>();
  }
  double positive(const std::string& key) {
    const json& v = get(key);
    if (!v.is_number() || !(v.get<double>() > 0.0) || !std::isfinite(v.get<double>())) {
      fail(key, fmt::format("must be a positive number, got {}", v.dump()));
    }
    return v.get<double>();
  }
  bool boolean(const std::string& key) {
    const json& v = get(key);
    if (!v.is_boolean()) fail(key, fmt::format("must be true or false, got {}", v.dump()));
    return v.get<bool>();
  }
  std::string string(const std::string& key) {
    const json& v = get(key);
    if (!v.is_string() || v.get<std::string>().empty()) {
      fail(key, fmt::format("must be a non-empty string, got {}", v.dump()));
    }
    return v.get<std::string>();
  }
  // One of `choices`; returns its index.
  std::size_t choice(const std::string& key, std::initializer_list<std::string_view> choices) {
    const std::string s = string(key);
    std::size_t i = 0;
    for (const auto c : choices) {
      if (s == c) return i;
      ++i;
    }
    fail(key, fmt::format("must be one of \"{}\", got \"{}\"", fmt::join(choices, "\", \""), s));
  }
  std::array<float, 3> triple(const std::string& key, bool positive_only) {
    const json& v = get(key);
    std::array<float, 3> out{};
    bool ok = v.is_array() && v.size() == 3;
    for (std::size_t i = 0; ok && i < 3; ++i) {
      ok = v[i].is_number() && std::isfinite(v[i].get<double>()) && (!positive_only || v[i].get<double>() > 0.0);
      if (ok) out[i] = v[i].get<float>();
    }
    if (!ok) {
      fail(key, fmt::format("must be an array of 3 {}numbers, got {}", positive_only ? "positive " : "", v.dump()));
    }
    return out;
  }
  Fields object(const std::string& key) {
    const json& v = get(key);
    if (!v.is_object()) fail(key, fmt::format("must be an object, got {}", v.dump()));
    return Fields(v, prefix_ + key + ".", file_);
  }
  void expect_all_read() const {
    for (const auto& [key, value] : object_.items()) {
      if (!read_.count(key)) fail(key, "is not a known field here (typo, or a field of another model kind?)");
    }
  }
  [[noreturn]] void fail(const std::string& key, const std::string& what) const {
    throw Error(fmt::format("model manifest {}: field '{}{}' {}", file_.string(), prefix_, key, what));
  }

 private:
  const json& object_;
  std::string prefix_;
  const fs::path& file_;
  std::set<std::string> read_;
};

ImageInputSpec read_image_input(Fields f) {
  ImageInputSpec s;
  s.height = f.integer("height", 1, kMaxSide);
  s.width = f.integer("width", 1, kMaxSide);
  s.resize = static_cast<ResizePolicy>(f.choice("resize", {"exact", "resize", "resize_short_center_crop"}));
  constexpr int kInterpolations[] = {cv::INTER_NEAREST, cv::INTER_LINEAR, cv::INTER_CUBIC, cv::INTER_AREA};
  s.interpolation = kInterpolations[f.choice("interpolation", {"nearest", "bilinear", "bicubic", "area"})];
  s.bgr = f.choice("channel_order", {"RGB", "BGR"}) == 1;
  s.value_scale = static_cast<float>(f.positive("value_scale"));
  s.mean = f.triple("mean", false);
  s.std = f.triple("std", true);
  f.expect_all_read();
  return s;
}

OutputSpec read_output(Fields f, ModelKind kind) {
  OutputSpec s;
  s.dim = f.integer("dim", 1, kMaxDim);
  if (kind == ModelKind::kDenseImage) {
    s.height = f.integer("height", 1, kMaxSide);
    s.width = f.integer("width", 1, kMaxSide);
    f.choice("layout", {"CHW"});
  }
  s.l2_normalized = f.boolean("l2_normalized");
  s.normalize_output = f.boolean("normalize_output");
  f.expect_all_read();
  return s;
}

// Python's round(): half to even, as torchvision's CenterCrop uses.
int round_half_even(double v) { return static_cast<int>(std::nearbyint(v)); }

}  // namespace

std::string_view to_string(ModelKind kind) {
  switch (kind) {
    case ModelKind::kDenseImage: return "dense_image";
    case ModelKind::kImage: return "image";
    case ModelKind::kText: return "text";
  }
  return "?";
}

namespace {
ModelManifest parse_manifest_fields(std::string_view json_text, const fs::path& manifest_path);
}  // namespace

ModelManifest parse_model_manifest(std::string_view json_text, const fs::path& manifest_path) {
  // Every JSON access error (a value of another type or range than the field checks expect) is a
  // bad manifest, named as such, never an escaping nlohmann exception (found by fuzz_model_manifest).
  try {
    return parse_manifest_fields(json_text, manifest_path);
  } catch (const json::exception& e) {
    throw Error(fmt::format("model manifest {}: {}", manifest_path.string(), e.what()));
  }
}

namespace {
ModelManifest parse_manifest_fields(std::string_view json_text, const fs::path& manifest_path) {
  json root;
  try {
    root = json::parse(json_text);
  } catch (const json::parse_error& e) {
    throw Error(fmt::format("model manifest {}: not valid JSON: {}", manifest_path.string(), e.what()));
  }
  if (!root.is_object()) throw Error(fmt::format("model manifest {}: must be a JSON object", manifest_path.string()));

  Fields f(root, "", manifest_path);
  ModelManifest m;
  m.manifest_path = manifest_path;
  m.model_path = fs::path(manifest_path).replace_extension(".pt");
  f.integer("manifest_version", 1, 1);
  m.kind = static_cast<ModelKind>(f.choice("kind", {"dense_image", "image", "text"}));
  m.model_id = f.string("model_id");
  if (m.kind == ModelKind::kText) {
    Fields t = f.object("text");
    m.text.context_length = t.integer("context_length", 2, 1 << 16);
    m.text.vocab = manifest_path.parent_path() / t.string("vocab");
    t.expect_all_read();
  } else {
    m.input = read_image_input(f.object("input"));
  }
  m.output = read_output(f.object("output"), m.kind);
  if (f.has("runtime")) {
    Fields r = f.object("runtime");
    if (r.has("threads")) m.threads = r.integer("threads", 0, kMaxThreads);
    if (r.has("batch_size")) m.batch_size = r.integer("batch_size", 1, 4096);
    r.expect_all_read();
  }
  f.expect_all_read();
  // Sizes that could not be allocated are refused here, before the model is loaded.
  const double output_bytes = 4.0 * m.output.dim * m.output.height * m.output.width;
  if (m.kind == ModelKind::kDenseImage && output_bytes > kMaxTensorBytes)
    throw Error(fmt::format("model manifest {}: output {} x {} x {} (dim x height x width) is {:.0f} MB of float32 per "
                            "image, more than {:.0f} MB",
                            manifest_path.string(), m.output.dim, m.output.height, m.output.width, output_bytes / 1e6,
                            kMaxTensorBytes / 1e6));
  const double input_bytes = 12.0 * m.batch_size * m.input.height * m.input.width;
  if (m.kind != ModelKind::kText && input_bytes > kMaxTensorBytes)
    throw Error(fmt::format("model manifest {}: a batch of {} inputs of 3 x {} x {} is {:.0f} MB of float32, more than "
                            "{:.0f} MB (lower runtime.batch_size)",
                            manifest_path.string(), m.batch_size, m.input.height, m.input.width, input_bytes / 1e6,
                            kMaxTensorBytes / 1e6));
  return m;
}
}  // namespace

ModelManifest load_model_manifest(const fs::path& model_or_manifest) {
  const fs::path manifest_path = model_or_manifest.extension() == ".json"
                                     ? model_or_manifest
                                     : fs::path(model_or_manifest).replace_extension(".json");
  std::error_code ec;
  if (!fs::exists(manifest_path, ec) && !ec) {
    throw Error(
        fmt::format("model manifest {} not found (every MODEL.pt needs its MODEL.json beside it; "
                    "tools/export_lseg.py and tools/export_clip.py write both)",
                    manifest_path.string()));
  }
  return parse_model_manifest(read_regular_file(manifest_path, "model manifest", kMaxManifestBytes), manifest_path);
}

ResizePlan plan_resize(cv::Size image, const ImageInputSpec& spec, const std::string& source) {
  const cv::Size target(spec.width, spec.height);
  switch (spec.resize) {
    case ResizePolicy::kExact:
      if (image != target) {
        throw Error(
            fmt::format("image '{}' is {} x {} (w x h) but the model needs exactly {} x {} "
                        "(manifest input.resize = \"exact\")",
                        source, image.width, image.height, target.width, target.height));
      }
      return {image, cv::Rect({0, 0}, image)};
    case ResizePolicy::kResize: return {target, cv::Rect({0, 0}, target)};
    case ResizePolicy::kResizeShortCenterCrop: {
      // Scale so the image just covers the target; the other side is truncated like
      // torchvision's Resize(int), then a centre crop like torchvision's CenterCrop.
      const int64_t iw = image.width, ih = image.height;
      cv::Size scaled;
      if (int64_t{target.height} * iw >= int64_t{target.width} * ih) {
        scaled = {std::max<int>(target.width, static_cast<int>(iw * target.height / ih)), target.height};
      } else {
        scaled = {target.width, std::max<int>(target.height, static_cast<int>(ih * target.width / iw))};
      }
      const cv::Point corner(round_half_even((scaled.width - target.width) / 2.0),
                             round_half_even((scaled.height - target.height) / 2.0));
      return {scaled, cv::Rect(corner, target)};
    }
  }
  throw Error("unknown resize policy");
}

void image_to_network_input(const ImageFrame& frame, const ModelManifest& manifest, float* chw) {
  const std::string& source = frame.source.empty() ? std::string("<unnamed>") : frame.source;
  if (frame.rgb.empty()) throw Error(fmt::format("image '{}' has no RGB pixels", source));
  if (frame.rgb.type() != CV_8UC3) {
    throw Error(
        fmt::format("image '{}' must be 8-bit 3-channel RGB (CV_8UC3), got OpenCV type {}", source, frame.rgb.type()));
  }
  const ImageInputSpec& spec = manifest.input;
  const ResizePlan plan = plan_resize(frame.rgb.size(), spec, source);
  cv::Mat scaled = frame.rgb;
  if (plan.scaled != frame.rgb.size()) cv::resize(frame.rgb, scaled, plan.scaled, 0, 0, spec.interpolation);
  const cv::Mat fitted = scaled(plan.crop);

  std::array<float, 3> gain{}, offset{};
  for (int c = 0; c < 3; ++c) {
    gain[c] = spec.value_scale / spec.std[c];
    offset[c] = -spec.mean[c] / spec.std[c];
  }
  const std::size_t plane = static_cast<std::size_t>(spec.height) * spec.width;
  for (int y = 0; y < spec.height; ++y) {
    const auto* row = fitted.ptr<cv::Vec3b>(y);
    float* out = chw + static_cast<std::size_t>(y) * spec.width;
    for (int x = 0; x < spec.width; ++x) {
      for (int c = 0; c < 3; ++c) {
        const int source_channel = spec.bgr ? 2 - c : c;
        out[c * plane + x] = static_cast<float>(row[x][source_channel]) * gain[c] + offset[c];
      }
    }
  }
}

}  // namespace slamvdb
