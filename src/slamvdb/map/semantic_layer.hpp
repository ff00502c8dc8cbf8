#pragma once
// The semantic layer: for each visually observed voxel, a running-average embedding and an
// observation counter (paper Eq. 6.1). Most voxels are never seen by the camera, so this is a
// key -> entry store beside the occupancy grid rather than a field of every voxel.
//
// Beyond the paper, every entry also keeps the statistics of its observations that a confidence
// needs (8 bytes: VoxelStatistics): the sum of their weights (the count under Eq. 6.1, whose
// observations all weigh 1) and their spread, the weighted sum of squared distances from the mean,
// updated with West's weighted form of Welford's algorithm in the same pass as the mean; and the
// session that observed it last (2 bytes, issue 23: a uint16 SessionInfo::id, or kOwnSession for
// the submap's own session, which the layer is told: SemanticMap sets it when it takes a submap).
// Fusion never looks at it: every new entry is the submap's own; only merging submaps of
// different sessions (submap_merge.hpp) gives an entry another session.
//
// Entries live in chunks of kChunkSlots slots (keys, counts and embeddings side by side), so that
// a query can read them as contiguous blocks (for_each_chunk) and the memory per entry stays at
// the payload (no doubling on growth). An entry's handle (its slot) is stable until the entry is
// erased; with change tracking on, an erased slot is not reused until the change log has been
// taken, so a reader that holds handles (the global index) never sees a slot change meaning.
#include <absl/container/flat_hash_map.h>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <span>
#include <string_view>
#include <utility>
#include <vector>

#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/map/keys.hpp"

namespace slamvdb {

std::string_view to_string(EmbeddingPrecision p);
EmbeddingPrecision precision_from_string(std::string_view s);  // "fp32" | "fp16"; throws Error

struct SemanticParams {
  int dim = 512;
  // Storage precision at rest (finished submaps, files). fp16 is the default: at 512-d it halves
  // memory for a cosine error below 1e-5 (see semantic_layer_test and README).
  EmbeddingPrecision precision = EmbeddingPrecision::kFloat16;
  // A baseline, not a fusion rule: each voxel keeps its single best observation (the one of the
  // largest weight: fusion gives the nearest view the largest) instead of a mean, and so does the
  // global index across submaps. What classifying from one view per voxel scores.
  bool single_view = false;
};

// An entry's observation statistics. weight: the sum of the observations' weights (= count under
// the paper's rule). spread: sum_i w_i |x_i - mean|^2, NaN when unknown (entries of maps saved
// before statistics were kept; they load with weight = count).
struct VoxelStatistics {
  float weight = 0.f;
  float spread = 0.f;
  bool known() const { return spread == spread; }
};

// The statistics of `count` observations whose spread is not known (weight = count, spread NaN).
inline VoxelStatistics unknown_statistics(uint32_t count) {
  return {static_cast<float>(count), std::numeric_limits<float>::quiet_NaN()};
}

// Chan et al.'s pairwise combination of two sets' statistics, given the squared distance between
// their means: weights add, spreads add plus wa wb / (wa + wb) |ma - mb|^2.
inline VoxelStatistics combine_statistics(VoxelStatistics a, VoxelStatistics b, float squared_mean_distance) {
  const float w = a.weight + b.weight;
  if (!(w > 0.f)) return {w, a.spread + b.spread};
  return {w, a.spread + b.spread + a.weight * b.weight / w * squared_mean_distance};
}

class SemanticLayer {
 public:
  using Handle = uint32_t;
  static constexpr std::size_t kChunkSlots = 128;

  // params.precision is this layer's storage precision (convert_to changes it).
  explicit SemanticLayer(const SemanticParams& params = {});
  SemanticLayer(const SemanticLayer&) = delete;
  SemanticLayer& operator=(const SemanticLayer&) = delete;
  SemanticLayer(SemanticLayer&&) = default;
  SemanticLayer& operator=(SemanticLayer&&) = default;

  // Eq. 6.1 generalised to a weighted mean: W <- W + w, v <- v + (w / W)(x - v), n <- n + 1, the
  // spread by West's update. weight 1 (the paper's rule) gives Eq. 6.1 bit for bit: v <- (n v + x) /
  // (n + 1). A new entry starts at n = 0. weight must be > 0.
  void integrate(const VoxelKey& key, const float* observation, float weight = 1.0f);
  // The single-view baseline's rule (params.single_view): the entry becomes the observation when it
  // is new or `weight` exceeds the kept observation's; n <- n + 1 either way.
  void keep_best(const VoxelKey& key, const float* observation, float weight);
  // Eq. 6.1 for two means (merges, resampling): v <- (W v + W' m) / (W + W'), n <- n + c, the
  // statistics combined (combine_statistics); under single_view the entry of larger weight wins.
  void accumulate(const VoxelKey& key, const float* mean, uint32_t count, VoxelStatistics stats);
  // Without statistics: weight = count and the spread unknown (NaN; 0 would claim a perfectly
  // consistent voxel, the most confident value).
  void accumulate(const VoxelKey& key, const float* mean, uint32_t count) {
    accumulate(key, mean, count, unknown_statistics(count));
  }
  // Writes an entry as is. count must be >= 1; statistics default to weight = count, spread unknown.
  void set(const VoxelKey& key, const float* embedding, uint32_t count);
  void set(const VoxelKey& key, const float* embedding, uint32_t count, VoxelStatistics stats);
  // Bulk insert (map loading): n new keys, counts >= 1, n x dim values in this layer's precision,
  // and their statistics (empty: unknown, weight = count). Throws Error on a zero count or a key
  // that is already present.
  // sessions: each entry's last-observing session as stored (empty: all kOwnSession).
  void insert_raw(std::span<const VoxelKey> keys, std::span<const uint32_t> counts, const std::byte* embeddings,
                  std::span<const VoxelStatistics> stats = {}, std::span<const uint16_t> sessions = {});
  bool erase(const VoxelKey& key);

  std::optional<Handle> find(const VoxelKey& key) const;
  std::size_t size() const { return index_.size(); }
  int dim() const { return params_.dim; }
  EmbeddingPrecision precision() const { return params_.precision; }
  const SemanticParams& params() const { return params_; }

  // Entry accessors; valid handles come from find(), for_each() or the change log.
  const VoxelKey& key_of(Handle h) const { return chunk(h).keys[h % kChunkSlots]; }
  uint32_t count_of(Handle h) const { return chunk(h).counts[h % kChunkSlots]; }
  VoxelStatistics statistics_of(Handle h) const { return chunk(h).stats[h % kChunkSlots]; }
  float weight_of(Handle h) const { return chunk(h).stats[h % kChunkSlots].weight; }
  EmbeddingView embedding_of(Handle h) const { return {embedding(h), params_.precision}; }
  // The newest session that observed the entry (SessionInfo::id), and as stored (kOwnSession:
  // the submap's own session).
  static constexpr uint16_t kOwnSession = UINT16_MAX;
  int session_of(Handle h) const {
    const uint16_t s = stored_session_of(h);
    return s == kOwnSession ? own_session_ : s;
  }
  uint16_t stored_session_of(Handle h) const { return chunk(h).sessions[h % kChunkSlots]; }
  // Sets it: kOwnSession when `session` is the own session. Throws Error outside 0..65534.
  void set_session(Handle h, int session);
  // Whether any entry was last observed by another session than the submap's.
  bool has_other_sessions() const;

  // The submap's own session (SubmapInfo::session; 0 until set): what kOwnSession stands for.
  int own_session() const { return own_session_; }
  void set_own_session(int session);
  // Renumbers the own session and every entry's by new_id_of_old (maps of sessions merged into
  // one); throws Error, changing nothing, for a session it does not list.
  void renumber_sessions(const std::map<int, int>& new_id_of_old);
  void read(Handle h, float* out) const;  // decodes the embedding to fp32

  // Re-encodes every embedding (fp32 while a submap is written, the storage precision at rest).
  void convert_to(EmbeddingPrecision precision);

  // A chunk as stored: slot s holds an entry iff counts[s] > 0; its handle is first + s.
  struct ChunkView {
    Handle first;
    std::size_t slots;
    const VoxelKey* keys;
    const uint32_t* counts;
    const VoxelStatistics* stats;
    const uint16_t* sessions;     // each slot's last-observing session as stored (kOwnSession)
    const std::byte* embeddings;  // slots x dim values in `precision`, row after row
    EmbeddingPrecision precision;
  };
  template <class F>  // f(const ChunkView&)
  void for_each_chunk(F&& f) const {
    for (std::size_t c = 0; c < chunks_.size(); ++c) {
      const Chunk& ch = *chunks_[c];
      const std::size_t slots = std::min(kChunkSlots, slots_used_ - c * kChunkSlots);
      f(ChunkView{static_cast<Handle>(c * kChunkSlots), slots, ch.keys.data(), ch.counts.data(), ch.stats.data(),
                  ch.sessions.data(), ch.embeddings.get(), params_.precision});
    }
  }
  template <class F>  // f(Handle) for every entry, in storage order
  void for_each(F&& f) const {
    for_each_chunk([&](const ChunkView& v) {
      for (std::size_t s = 0; s < v.slots; ++s)
        if (v.counts[s]) f(static_cast<Handle>(v.first + s));
    });
  }

  // The change log that keeps a reader's references (the global index) in step.
  struct Changes {
    std::vector<Handle> added;                         // may already be erased again (count 0)
    std::vector<std::pair<Handle, VoxelKey>> erased;   // handle and the key it had
  };
  void set_change_tracking(bool on);
  Changes take_changes();  // and makes the erased slots reusable

  std::size_t memory_bytes() const;  // everything this layer allocates
  double bytes_per_entry() const { return size() ? static_cast<double>(memory_bytes()) / size() : 0.0; }

 private:
  struct Chunk {
    std::array<VoxelKey, kChunkSlots> keys;
    std::array<uint32_t, kChunkSlots> counts{};  // 0 marks a free slot
    std::array<VoxelStatistics, kChunkSlots> stats{};
    std::array<uint16_t, kChunkSlots> sessions{};
    std::unique_ptr<std::byte[]> embeddings;
  };
  Handle allocate(const VoxelKey& key);
  const Chunk& chunk(Handle h) const { return *chunks_[h / kChunkSlots]; }
  Chunk& chunk(Handle h) { return *chunks_[h / kChunkSlots]; }
  std::byte* embedding(Handle h) const {
    return chunks_[h / kChunkSlots]->embeddings.get() + (h % kChunkSlots) * bytes_per_embedding_;
  }
  uint32_t& count_ref(Handle h) { return chunk(h).counts[h % kChunkSlots]; }
  VoxelStatistics& stats_ref(Handle h) { return chunk(h).stats[h % kChunkSlots]; }
  // h's embedding in the layer's precision: written from dim floats, zeroed, or moved a step
  // towards x (v += step (x - v), returning |x - v_old|^2).
  void store_embedding(Handle h, const float* values);
  void zero_embedding(Handle h);
  float step_embedding(Handle h, const float* x, float step);

  SemanticParams params_;
  std::size_t bytes_per_embedding_;
  int own_session_ = 0;
  absl::flat_hash_map<VoxelKey, Handle> index_;
  std::vector<std::unique_ptr<Chunk>> chunks_;
  std::size_t slots_used_ = 0;  // slots ever handed out (the used prefix of the chunks)
  std::vector<Handle> free_slots_;
  bool tracking_ = false;
  Changes changes_;
  std::vector<Handle> pending_free_;  // erased while tracking: reusable after take_changes()
};

}  // namespace slamvdb
