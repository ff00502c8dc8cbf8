#pragma once
// The server's text encoder, loaded once, with an LRU cache of text embeddings: a planner asks the
// same few texts again and again, and a CLIP text forward pass costs far more than a look-up.
// The encoder runs under a lock (encoders are not required to be thread-safe); a hit does not wait
// for a running encode of another text longer than the map look-up it guards.
#include <Eigen/Core>
#include <cstddef>
#include <list>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>

#include "slamvdb/inference/encoders.hpp"

namespace slamvdb {

// What every answer says about the encoder that embedded its text.
struct TextEncoderInfo {
  std::string model_id;
  bool simulated = false;
};

class TextEmbeddingCache {
 public:
  TextEmbeddingCache(std::unique_ptr<TextEncoder> encoder, bool simulated, std::size_t capacity = 4096);
  const TextEncoderInfo& info() const { return info_; }
  int dim() const { return dim_; }
  // The text's embedding, from the cache or the encoder (whose Error passes through).
  Eigen::VectorXf embed(std::string_view text);
  struct Counts {
    std::size_t hits = 0, misses = 0, size = 0;
  };
  Counts counts() const;

 private:
  using Entry = std::pair<std::string, Eigen::VectorXf>;
  std::unique_ptr<TextEncoder> encoder_;
  TextEncoderInfo info_;
  int dim_ = 0;
  std::size_t capacity_;
  mutable std::mutex cache_mutex_;
  std::mutex encoder_mutex_;
  std::list<Entry> lru_;  // most recent first
  std::unordered_map<std::string, std::list<Entry>::iterator> by_text_;
  std::size_t hits_ = 0, misses_ = 0;
};

}  // namespace slamvdb
