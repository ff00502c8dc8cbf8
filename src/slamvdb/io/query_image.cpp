#include "slamvdb/io/query_image.hpp"

#include "slamvdb/io/image_io.hpp"

namespace slamvdb {

QueryImageEncoder::QueryImageEncoder(std::unique_ptr<ImageEncoder> encoder, bool reads_labels)
    : encoder_(std::move(encoder)), reads_labels_(reads_labels), model_id_(encoder_->model_id()), dim_(encoder_->dim()) {}

std::vector<float> QueryImageEncoder::embed(const ImageRecord& record, std::int64_t max_pixels) {
  // Decoded outside the lock (a large PNG costs more than a look-up); only the encoder is shared.
  const ImageFrame frame = load_image_frame(record, !reads_labels_, reads_labels_, max_pixels);
  const std::lock_guard lock(mutex_);
  return encoder_->encode(frame);
}

std::vector<float> QueryImageEncoder::embed_file(const std::filesystem::path& image, std::int64_t max_pixels) {
  ImageRecord record;
  (reads_labels_ ? record.labels : record.rgb) = image;
  return embed(record, max_pixels);
}

std::vector<float> QueryImageEncoder::embed_bytes(std::string_view bytes, const std::string& name,
                                                  std::int64_t max_pixels) {
  auto data = std::make_shared<ImageBytes>();
  data->data.assign(bytes.begin(), bytes.end());
  data->name = name;  // channels 0: encoded PNG / JPEG, sized from its header before decoding
  ImageRecord record;
  (reads_labels_ ? record.label_data : record.rgb_data) = std::move(data);
  return embed(record, max_pixels);
}

}  // namespace slamvdb
