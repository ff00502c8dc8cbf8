#pragma once
// The TorchScript encoders as the commands get them: from the TorchScript backend, a plugin library
// (libslamvdb_torch_inference.so, core/plugin_library.hpp) loaded on the first call, so that only a
// run that opens a network pays libtorch's start-up (0.7-1.0 s of CPU per process, measured on the
// CLI's `--help`). The encoders are torch_encoders.hpp's classes; code that links slamvdb_torch (the
// Python module, the tests) may construct those directly. This header includes no torch header.
#include <filesystem>
#include <memory>

#include "slamvdb/inference/encoders.hpp"

namespace slamvdb {

struct TorchEncoderOptions {
  int threads = -1;     // libtorch intra-op threads; -1 takes the manifest's runtime.threads
  bool warm_up = true;  // one dummy pass on construction, checking the output against the manifest
};

// Each throws Error when this slamvdb was built without TorchScript support, when the backend
// cannot be loaded (naming where it was looked for), or as the encoder's constructor does.
std::unique_ptr<DenseImageEncoder> open_torch_dense_image_encoder(const std::filesystem::path& model_or_manifest,
                                                                  const TorchEncoderOptions& options = {});
std::unique_ptr<ImageEncoder> open_torch_image_encoder(const std::filesystem::path& model_or_manifest,
                                                       const TorchEncoderOptions& options = {});
std::unique_ptr<TextEncoder> open_torch_text_encoder(const std::filesystem::path& model_or_manifest,
                                                     const TorchEncoderOptions& options = {});

// What the backend library exports (torch_plugin.cpp), by kTorchEncodersSymbol. The version is
// checked, so that a stale library from another build is refused, not called.
struct TorchEncoderFactories {
  int version = 0;
  std::unique_ptr<DenseImageEncoder> (*dense_image)(const std::filesystem::path&, const TorchEncoderOptions&) = nullptr;
  std::unique_ptr<ImageEncoder> (*image)(const std::filesystem::path&, const TorchEncoderOptions&) = nullptr;
  std::unique_ptr<TextEncoder> (*text)(const std::filesystem::path&, const TorchEncoderOptions&) = nullptr;
};
inline constexpr int kTorchEncodersVersion = 1;
inline constexpr const char* kTorchEncodersSymbol = "slamvdb_torch_encoder_factories";

}  // namespace slamvdb
