#pragma once
// An image as a query (`slamvdb query --image FILE`, POST /api/query "image"): a PNG or JPEG,
// sized from its header before any pixel is decoded, embedded by an image encoder into one vector.
// A network reads the image in colour (RGB); the SIMULATED image encoder reads it as a 2D label
// image (8-bit RELLIS-3D class ids). One function for the file and for bytes from a request, so
// that the server embeds an image exactly as the command does.
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <vector>

#include "slamvdb/inference/encoders.hpp"
#include "slamvdb/io/dataset.hpp"

namespace slamvdb {

class QueryImageEncoder {
 public:
  // `reads_labels`: the encoder reads ImageFrame::labels (the SIMULATED one), else ImageFrame::rgb.
  QueryImageEncoder(std::unique_ptr<ImageEncoder> encoder, bool reads_labels);
  std::string model_id() const { return model_id_; }
  int dim() const { return dim_; }
  bool reads_labels() const { return reads_labels_; }
  // The embedding of an image file. Throws Error naming the file (unreadable, not PNG / JPEG, more
  // than `max_pixels` pixels, a label image that is not 8-bit class ids, ...).
  std::vector<float> embed_file(const std::filesystem::path& image, std::int64_t max_pixels = kDefaultMaxImagePixels);
  // The same for the encoded bytes of a PNG or JPEG in memory; `name` names it in messages.
  std::vector<float> embed_bytes(std::string_view bytes, const std::string& name,
                                 std::int64_t max_pixels = kDefaultMaxImagePixels);

 private:
  std::vector<float> embed(const ImageRecord& record, std::int64_t max_pixels);
  std::unique_ptr<ImageEncoder> encoder_;
  bool reads_labels_;
  std::string model_id_;
  int dim_;
  std::mutex mutex_;  // encoders need not be thread-safe (the server embeds from request threads)
};

}  // namespace slamvdb
