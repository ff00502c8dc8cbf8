// The TorchScript backend's entry point (torch_backend.hpp): the one symbol the plugin library
// libslamvdb_torch_inference.so exports.
#include "slamvdb/inference/torch_backend.hpp"
#include "slamvdb/inference/torch_encoders.hpp"

namespace {

template <class Encoder, class Interface>
std::unique_ptr<Interface> make(const std::filesystem::path& model_or_manifest, const slamvdb::TorchEncoderOptions& o) {
  return std::make_unique<Encoder>(model_or_manifest, o);
}

}  // namespace

extern "C" __attribute__((visibility("default"))) const slamvdb::TorchEncoderFactories* slamvdb_torch_encoder_factories() {
  static const slamvdb::TorchEncoderFactories factories{
      slamvdb::kTorchEncodersVersion,
      &make<slamvdb::TorchDenseImageEncoder, slamvdb::DenseImageEncoder>,
      &make<slamvdb::TorchImageEncoder, slamvdb::ImageEncoder>,
      &make<slamvdb::TorchTextEncoder, slamvdb::TextEncoder>,
  };
  return &factories;
}
