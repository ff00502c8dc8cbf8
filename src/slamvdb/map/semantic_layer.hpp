#pragma once
// The semantic layer: for each visually observed voxel, a running-average embedding and an
// observation counter (paper Eq. 6.1). Most voxels are never seen by the camera, so this is a
// key -> slot index beside the occupancy grid rather than a field of every voxel.
#include <absl/container/flat_hash_map.h>

#include <cstddef>
#include <memory>
#include <cstdint>
#include <optional>
#include <string_view>
#include <vector>

#include "slamvdb/core/types.hpp"
#include "slamvdb/map/occupancy_grid.hpp"

namespace slamvdb {

// fp16 is the default: at 512-d it halves memory (1024 B instead of 2048 B of embedding per
// voxel) for a cosine error below 1e-5 (see semantic_layer_test and README).
enum class EmbeddingPrecision : uint8_t { kFloat32 = 0, kFloat16 = 1 };
std::string_view to_string(EmbeddingPrecision p);
EmbeddingPrecision precision_from_string(std::string_view s);  // "fp32" | "fp16"; throws Error

struct SemanticParams {
  int dim = 512;
  EmbeddingPrecision precision = EmbeddingPrecision::kFloat16;
};

class SemanticLayer {
 public:
  using Slot = uint32_t;
  explicit SemanticLayer(const SemanticParams& params = {});

  // Eq. 6.1: v <- (n v + obs) / (n + 1), n <- n + 1; a new entry starts at n = 0.
  void integrate(const VoxelKey& key, const float* observation);
  // Writes an entry as is (map loading, merging). count must be >= 1.
  void set(const VoxelKey& key, const float* embedding, uint32_t count);
  bool erase(const VoxelKey& key);

  std::optional<Slot> find(const VoxelKey& key) const;
  std::size_t size() const { return index_.size(); }
  int dim() const { return params_.dim; }
  EmbeddingPrecision precision() const { return params_.precision; }
  const SemanticParams& params() const { return params_; }

  // Slot accessors; valid slots come from find() or for_each().
  uint32_t count_at(Slot s) const { return counts_[s]; }
  void read(Slot s, float* out) const;  // decodes the embedding to fp32

  template <class F>  // f(const VoxelKey&, Slot)
  void for_each(F&& f) const {
    for (const auto& [key, slot] : index_) f(key, slot);
  }

  std::size_t memory_bytes() const;  // everything this layer allocates
  double bytes_per_entry() const { return size() ? static_cast<double>(memory_bytes()) / size() : 0.0; }

 private:
  // Embeddings live in fixed-size chunks, not one growing vector, so the memory per entry stays
  // at the payload instead of up to twice it after a reallocation.
  static constexpr std::size_t kChunkSlots = 128;
  Slot allocate(const VoxelKey& key);
  std::byte* embedding(Slot s) const {
    return chunks_[s / kChunkSlots].get() + (s % kChunkSlots) * bytes_per_embedding_;
  }

  SemanticParams params_;
  std::size_t bytes_per_embedding_;
  absl::flat_hash_map<VoxelKey, Slot, VoxelKeyAbslHash> index_;
  std::vector<uint32_t> counts_;  // per slot; 0 marks a free slot
  std::vector<std::unique_ptr<std::byte[]>> chunks_;
  std::vector<Slot> free_slots_;
};

}  // namespace slamvdb
