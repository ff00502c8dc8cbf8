#include "slamvdb/server/text_embedding_cache.hpp"

namespace slamvdb {

TextEmbeddingCache::TextEmbeddingCache(std::unique_ptr<TextEncoder> encoder, bool simulated, std::size_t capacity)
    : encoder_(std::move(encoder)), capacity_(std::max<std::size_t>(capacity, 1)) {
  info_ = {encoder_->model_id(), simulated};
  dim_ = encoder_->dim();
}

Eigen::VectorXf TextEmbeddingCache::embed(std::string_view text) {
  const std::string key(text);
  {
    std::lock_guard lock(cache_mutex_);
    if (const auto it = by_text_.find(key); it != by_text_.end()) {
      lru_.splice(lru_.begin(), lru_, it->second);
      ++hits_;
      return it->second->second;
    }
    ++misses_;
  }
  // Encoded outside the cache lock, so hits never wait for a forward pass; two threads missing on
  // the same text both encode it (same answer), the second insert finds it present.
  std::vector<float> v;
  {
    std::lock_guard lock(encoder_mutex_);
    v = encoder_->encode(text);
  }
  Eigen::VectorXf e = Eigen::Map<const Eigen::VectorXf>(v.data(), static_cast<Eigen::Index>(v.size()));
  std::lock_guard lock(cache_mutex_);
  if (!by_text_.count(key)) {
    lru_.emplace_front(key, e);
    by_text_[key] = lru_.begin();
    if (lru_.size() > capacity_) {
      by_text_.erase(lru_.back().first);
      lru_.pop_back();
    }
  }
  return e;
}

TextEmbeddingCache::Counts TextEmbeddingCache::counts() const {
  std::lock_guard lock(cache_mutex_);
  return {hits_, misses_, lru_.size()};
}

}  // namespace slamvdb
