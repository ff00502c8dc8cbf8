#pragma once
// The JSON manifest that travels beside every exported network (MODEL.pt + MODEL.json): what the
// network is, how to turn a camera image or a text into its input, and what it must output.
// tools/export_lseg.py, export_clip.py and make_test_models.py write these files.
#include <array>
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <string_view>

#include "slamvdb/inference/encoders.hpp"

namespace slamvdb {

enum class ModelKind { kDenseImage, kImage, kText };
std::string_view to_string(ModelKind kind);  // the manifest's spelling: dense_image, image, text

enum class ResizePolicy {
  kExact,                  // "exact": the image must already have the input size
  kResize,                 // "resize": scale to the input size, aspect ratio not kept
  kResizeShortCenterCrop,  // "resize_short_center_crop": CLIP's resize + centre crop
};

struct ImageInputSpec {
  int height = 0, width = 0;
  ResizePolicy resize = ResizePolicy::kExact;
  int interpolation = cv::INTER_AREA;  // "nearest" | "bilinear" | "bicubic" | "area"
  bool bgr = false;                    // channel order the network expects ("RGB" | "BGR")
  // network value = (pixel * value_scale - mean[c]) / std[c], c in the network's channel order
  float value_scale = 1.0f;
  std::array<float, 3> mean{}, std{};
};

struct TextInputSpec {
  int context_length = 77;
  std::filesystem::path vocab;  // CLIP merge list, resolved against the manifest's directory
};

struct OutputSpec {
  int dim = 0;
  int height = 0, width = 0;      // dense_image only; the layout is "CHW" (N x C x H x W tensor)
  bool l2_normalized = false;     // the network already outputs unit vectors (checked on warm-up)
  bool normalize_output = false;  // the backend L2-normalises every output vector
};

struct ModelManifest {
  ModelKind kind = ModelKind::kDenseImage;
  std::string model_id;
  std::filesystem::path manifest_path, model_path;  // model_path: the manifest with extension .pt
  ImageInputSpec input;                             // dense_image, image
  TextInputSpec text;                               // text
  OutputSpec output;
  int threads = 0;  // intra-op threads, at most 256; 0 keeps the library's default
  int batch_size = 1;
};

// Largest manifest read: 1 MiB (they are a few hundred bytes).
inline constexpr std::uint64_t kMaxManifestBytes = std::uint64_t{1} << 20;

// Accepts MODEL.pt or MODEL.json and reads MODEL.json (a regular file: a FIFO is an Error). Every
// field is checked; a missing file, malformed JSON, missing / mistyped / unknown / out-of-range
// field throws Error naming the file and the field, and so do sizes that cannot be allocated
// (runtime.threads above 256, output.dim above 4096, more than 1 GiB of float32 per input batch
// or per output image). The model file itself is not opened here.
ModelManifest load_model_manifest(const std::filesystem::path& model_or_manifest);

// The same from JSON text; `manifest_path` names the file in messages and anchors relative paths.
ModelManifest parse_model_manifest(std::string_view json_text, const std::filesystem::path& manifest_path);

// Geometry of the resize policy: scale the image to `scaled`, then cut `crop` out of it.
struct ResizePlan {
  cv::Size scaled;
  cv::Rect crop;
};
// Throws Error if the policy is "exact" and the size differs (`source` names the image).
ResizePlan plan_resize(cv::Size image, const ImageInputSpec& spec, const std::string& source);

// Pre-processes one RGB frame (CV_8UC3) into the network's 3 x height x width float input at
// `chw`, per the manifest. Throws Error naming the frame for an empty or non-8-bit-RGB image.
void image_to_network_input(const ImageFrame& frame, const ModelManifest& manifest, float* chw);

}  // namespace slamvdb
