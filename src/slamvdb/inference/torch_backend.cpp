#include "slamvdb/inference/torch_backend.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/plugin_library.hpp"

namespace slamvdb {
namespace {

const TorchEncoderFactories& torch_encoders() {
#ifdef SLAMVDB_TORCH_INFERENCE_PLUGIN
  static const TorchEncoderFactories* factories = [] {
    using Entry = const TorchEncoderFactories* (*)();
    const auto entry = reinterpret_cast<Entry>(
        plugin_symbol(SLAMVDB_TORCH_INFERENCE_PLUGIN, kTorchEncodersSymbol, "the TorchScript backend"));
    const TorchEncoderFactories* f = entry();
    if (f->version != kTorchEncodersVersion)
      throw Error(fmt::format("the TorchScript backend {} is version {}, this slamvdb needs {}: it is from another "
                              "build (rebuild or reinstall both)",
                              SLAMVDB_TORCH_INFERENCE_PLUGIN, f->version, kTorchEncodersVersion));
    return f;
  }();
  return *factories;
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
