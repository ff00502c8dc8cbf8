#pragma once
// The real networks: TorchScript modules (MODEL.pt) described by a manifest (MODEL.json, see
// model_manifest.hpp), run on the CPU with libtorch. Only torch_encoders.cpp includes torch
// headers, so everything else compiles without them. Built when SLAMVDB_WITH_TORCH is on, into the
// plugin library that torch_backend.hpp loads (the CLI) and into slamvdb_torch (Python, tests).
//
// Every encoder: checks the manifest against the network with one dummy pass on construction
// (warm-up), pre-processes images in C++ exactly as the manifest says, runs without autograd,
// and reports a missing file, a manifest / network mismatch, a wrongly sized image or a failing
// network as an Error naming the model.
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "slamvdb/inference/encoders.hpp"
#include "slamvdb/inference/model_manifest.hpp"
#include "slamvdb/inference/torch_backend.hpp"  // TorchEncoderOptions

namespace slamvdb {

// image -> per-pixel embeddings (LSeg): the network maps N x 3 x H x W to N x C x h x w.
class TorchDenseImageEncoder final : public DenseImageEncoder {
 public:
  explicit TorchDenseImageEncoder(const std::filesystem::path& model_or_manifest,
                                  const TorchEncoderOptions& options = {});
  ~TorchDenseImageEncoder() override;

  FeatureMap encode(const ImageFrame& frame) override;
  // One map per frame, in order; runs runtime.batch_size frames per network pass.
  std::vector<FeatureMap> encode_batch(const std::vector<ImageFrame>& frames);
  int dim() const override;
  std::string model_id() const override;
  const ModelManifest& manifest() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// image -> one embedding (CLIP encode_image): N x 3 x H x W to N x C.
class TorchImageEncoder final : public ImageEncoder {
 public:
  explicit TorchImageEncoder(const std::filesystem::path& model_or_manifest, const TorchEncoderOptions& options = {});
  ~TorchImageEncoder() override;

  std::vector<float> encode(const ImageFrame& frame) override;
  int dim() const override;
  std::string model_id() const override;
  const ModelManifest& manifest() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

// text -> one embedding (CLIP encode_text): CLIP-tokenised 1 x context_length int64 to 1 x C.
class TorchTextEncoder final : public TextEncoder {
 public:
  explicit TorchTextEncoder(const std::filesystem::path& model_or_manifest, const TorchEncoderOptions& options = {});
  ~TorchTextEncoder() override;

  std::vector<float> encode(std::string_view text) override;
  int dim() const override;
  std::string model_id() const override;
  const ModelManifest& manifest() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace slamvdb
