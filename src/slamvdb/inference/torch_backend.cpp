#include "slamvdb/inference/torch_backend.hpp"


#include "slamvdb/core/error.hpp"
#include "slamvdb/core/plugin_library.hpp"

namespace slamvdb {
namespace {

const TorchEncoderFactories& torch_encoders() {
#ifdef SLAMVDB_TORCH_INFERENCE_PLUGIN
  static const TorchEncoderFactories& factories = plugin_exports<TorchEncoderFactories>(
      SLAMVDB_TORCH_INFERENCE_PLUGIN, kTorchEncodersSymbol, "the TorchScript backend", kTorchEncodersVersion);
  return factories;
#else
  throw Error("this slamvdb was built without TorchScript support (SLAMVDB_WITH_TORCH=OFF)");
#endif
}

}  // namespace

std::unique_ptr<DenseImageEncoder> open_torch_dense_image_encoder(const std::filesystem::path& model_or_manifest,
                                                                  const TorchEncoderOptions& options) {
  return torch_encoders().dense_image(model_or_manifest, options);
}

std::unique_ptr<ImageEncoder> open_torch_image_encoder(const std::filesystem::path& model_or_manifest,
                                                       const TorchEncoderOptions& options) {
  return torch_encoders().image(model_or_manifest, options);
}

std::unique_ptr<TextEncoder> open_torch_text_encoder(const std::filesystem::path& model_or_manifest,
                                                     const TorchEncoderOptions& options) {
  return torch_encoders().text(model_or_manifest, options);
}

}  // namespace slamvdb
