#include "slamvdb/query/ann_index.hpp"

#include <faiss/Clustering.h>
#include <faiss/IndexFlat.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>

#include <algorithm>
#include <climits>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>

#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/query/ann_index_codes.hpp"

namespace slamvdb {
namespace ann_index_detail {

using FaissId = faiss::Index::idx_t;

// Cell i's embedding as a unit fp32 vector in `out`; false when it has no direction (zero or not
// finite: similarity_search never answers such a cell, so it is left out of every list).
bool unit_embedding_of(const GlobalIndex& index, std::size_t i, float* out, std::size_t dim) {
  const IndexedVoxel v = index.read(i, out);  // a shared cell's mean is written into out itself
  if (v.embedding.data != out) kernels::decode(v.embedding, out, dim);
  double n2 = 0;
  for (std::size_t d = 0; d < dim; ++d) n2 += static_cast<double>(out[d]) * out[d];
  if (!(n2 > 0) || !std::isfinite(n2)) return false;
  const auto inv = static_cast<float>(1.0 / std::sqrt(n2));
  for (std::size_t d = 0; d < dim; ++d) out[d] *= inv;
  return true;
}

std::size_t default_lists(std::size_t cells) {
  const auto l = static_cast<std::size_t>(std::sqrt(static_cast<double>(cells)) / 4.0);
  return std::clamp<std::size_t>(l, 8, 1024);
}

}  // namespace ann_index_detail

struct AnnIndex::Impl {
  std::size_t dim = 0;
  Eigen::MatrixXf centroid_rows;     // lists x dim: a question's list similarities, without OpenMP
  std::vector<ann_codes::Sq8Codebook> codebooks;  // per list: of its cells' residuals to its centroid
  std::vector<std::size_t> list_begin;  // list l's cells: [list_begin[l], list_begin[l + 1])
  std::vector<uint32_t> positions;      // cell positions list by list, ascending within a list
  // Their codes' planes, plane_bytes() each, in the same order: the coarse one is scanned, the fine
  // one read for the best few of that scan.
  std::vector<uint8_t> coarse, fine;
  std::size_t index_size = 0;
  std::size_t rerank_factor = 2, rerank_min = 128, refine_factor = 3;
  AnnIndexStats stats;
};

AnnIndex::AnnIndex(const SemanticMap& map, const AnnOptions& options) : impl_(std::make_unique<Impl>()) {
  using namespace ann_index_detail;
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto dim = static_cast<std::size_t>(map.params().semantic.dim);
  Impl& m = *impl_;
  m.dim = dim;
  m.rerank_factor = std::max<std::size_t>(options.rerank_factor, 1);
  m.rerank_min = options.rerank_min;
  m.refine_factor = std::max<std::size_t>(options.refine_factor, 1);
  map.read_index([&](const GlobalIndex& index) {
    const std::size_t n = index.size();
    if (index.size() > UINT32_MAX) throw Error("the ANN index holds at most 2^32 cells");
    m.index_size = n;
    // Cells are decoded to unit fp32 vectors a batch at a time (never the whole map at once).
    std::vector<float> batch;
    std::vector<uint8_t> valid;
    auto decode_batch = [&](const std::vector<std::size_t>& positions) {
      batch.resize(positions.size() * dim);
      valid.assign(positions.size(), 0);
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, positions.size(), 256), [&](const auto& range) {
        for (std::size_t j = range.begin(); j != range.end(); ++j)
          valid[j] = unit_embedding_of(index, positions[j], batch.data() + j * dim, dim) ? 1 : 0;
      });
    };
    // k-means on an evenly spaced sample (deterministic: the same map gives the same index).
    const std::size_t wanted_lists = options.lists ? options.lists : default_lists(n);
    const std::size_t sample_wanted = options.training_cells ? options.training_cells : 64 * wanted_lists;
    const std::size_t sample_target = std::min(std::max<std::size_t>(sample_wanted, 1), n);
    std::vector<std::size_t> positions;
    for (std::size_t s = 0; s < sample_target; ++s) positions.push_back(s * n / sample_target);
    decode_batch(positions);
    std::vector<float> training;
    for (std::size_t j = 0; j < positions.size(); ++j)
      if (valid[j]) training.insert(training.end(), batch.begin() + static_cast<std::ptrdiff_t>(j * dim),
                                    batch.begin() + static_cast<std::ptrdiff_t>((j + 1) * dim));
    const std::size_t sample = training.size() / dim;
    if (options.stop && *options.stop) throw Error("the ANN index build was stopped");
    if (sample == 0) throw Error("the map has no semantic cell with a non-zero embedding to index");
    const std::size_t lists = std::min(wanted_lists, sample);
    faiss::ClusteringParameters params;
    params.niter = options.iterations;
    params.spherical = true;  // centroids on the unit sphere: inner product is cosine
    params.seed = 1234;
    params.max_points_per_centroid = static_cast<int>(sample / lists + 1);
    params.min_points_per_centroid = 1;
    faiss::Clustering clustering(static_cast<int>(dim), lists, params);
    faiss::IndexFlatIP centroids(static_cast<FaissId>(dim));  // also the build's batched assignment
    const auto training_start = Clock::now();
    clustering.train(static_cast<FaissId>(sample), training.data(), centroids);
    m.stats.training_seconds = std::chrono::duration<double>(Clock::now() - training_start).count();
    training = {};
    m.centroid_rows = Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
        centroids.get_xb(), static_cast<Eigen::Index>(lists), static_cast<Eigen::Index>(dim));
    // Two passes over the cells, a batch at a time. First each cell goes into the list of its most
    // similar centroid (faiss batches this with BLAS) and widens its list's residual ranges; then
    // (decoding again is cheap beside the assignment) its residual is coded with its list's ranges.
    // Ranges per list, not for the whole map: a list of cells between two kinds of surface spans a
    // wide range where the lists of one kind span a narrow one, and their codes must tell those
    // cells apart to a fraction of their noise.
    std::vector<int32_t> cell_list(n, -1);
    std::vector<float> low(lists * dim, std::numeric_limits<float>::infinity());
    std::vector<float> high(lists * dim, -std::numeric_limits<float>::infinity());
    std::vector<float> distance;
    std::vector<FaissId> label;
    const auto residual = [&](std::size_t j, std::size_t l) {
      float* x = batch.data() + j * dim;
      const float* c = centroids.get_xb() + l * dim;
      for (std::size_t d = 0; d < dim; ++d) x[d] -= c[d];
      return x;
    };
    constexpr std::size_t kBatch = 16384;
    const auto batch_of = [&](std::size_t b) {
      if (options.stop && *options.stop) throw Error("the ANN index build was stopped");
      const std::size_t k = std::min(kBatch, n - b);
      positions.resize(k);
      for (std::size_t j = 0; j < k; ++j) positions[j] = b + j;
      decode_batch(positions);
      return k;
    };
    for (std::size_t b = 0; b < n; b += kBatch) {
      const std::size_t k = batch_of(b);
      distance.resize(k);
      label.resize(k);
      centroids.search(static_cast<FaissId>(k), batch.data(), 1, distance.data(), label.data());
      for (std::size_t j = 0; j < k; ++j) {
        if (!valid[j] || label[j] < 0) continue;
        const auto l = static_cast<std::size_t>(label[j]);
        cell_list[b + j] = static_cast<int32_t>(l);
        const float* x = residual(j, l);
        for (std::size_t d = 0; d < dim; ++d) {
          low[l * dim + d] = std::min(low[l * dim + d], x[d]);
          high[l * dim + d] = std::max(high[l * dim + d], x[d]);
        }
      }
    }
    m.codebooks.resize(lists);
    for (std::size_t l = 0; l < lists; ++l)
      m.codebooks[l] = ann_codes::Sq8Codebook(std::vector<float>(low.begin() + static_cast<std::ptrdiff_t>(l * dim),
                                                                 low.begin() + static_cast<std::ptrdiff_t>((l + 1) * dim)),
                                              std::vector<float>(high.begin() + static_cast<std::ptrdiff_t>(l * dim),
                                                                 high.begin() + static_cast<std::ptrdiff_t>((l + 1) * dim)));
    m.list_begin.assign(lists + 1, 0);
    for (const int32_t l : cell_list)
      if (l >= 0) ++m.list_begin[static_cast<std::size_t>(l) + 1];
    for (std::size_t l = 0; l < lists; ++l) m.list_begin[l + 1] += m.list_begin[l];
    const std::size_t cells = m.list_begin[lists];
    const std::size_t bytes = m.codebooks[0].plane_bytes();
    m.positions.resize(cells);
    m.coarse.resize(cells * bytes);
    m.fine.resize(cells * bytes);
    std::vector<std::size_t> slot(n);
    std::vector<std::size_t> next(m.list_begin.begin(), m.list_begin.end() - 1);
    for (std::size_t i = 0; i < n; ++i) {
      if (cell_list[i] < 0) continue;
      slot[i] = next[static_cast<std::size_t>(cell_list[i])]++;
      m.positions[slot[i]] = static_cast<uint32_t>(i);
    }
    for (std::size_t b = 0; b < n; b += kBatch) {
      const std::size_t k = batch_of(b);
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, k, 1024), [&](const auto& range) {
        for (std::size_t j = range.begin(); j != range.end(); ++j) {
          const int32_t l = cell_list[b + j];
          if (l < 0) continue;
          const std::size_t at = slot[b + j];
          m.codebooks[static_cast<std::size_t>(l)].encode(residual(j, static_cast<std::size_t>(l)), m.coarse.data() + at * bytes,
                                                         m.fine.data() + at * bytes);
        }
      });
    }
    m.stats.cells = cells;
    m.stats.lists = lists;
  });
  m.stats.probes = options.probes ? std::min(options.probes, m.stats.lists) : std::max<std::size_t>(1, m.stats.lists / 8);
  m.stats.memory_bytes = m.stats.lists * dim * sizeof(float) * 3 + m.positions.size() * sizeof(uint32_t) +
                         m.coarse.size() + m.fine.size() + m.list_begin.size() * sizeof(std::size_t);
  m.stats.build_seconds = std::chrono::duration<double>(Clock::now() - start).count();
}

AnnIndex::~AnnIndex() = default;

std::vector<std::size_t> AnnIndex::candidates(std::span<const float> unit_query, std::size_t probes,
                                              std::size_t top_k, std::size_t* scanned, const Deadline& deadline) const {
  const Impl& m = *impl_;
  if (unit_query.size() != m.dim)
    throw Error(fmt::format("the ANN index is {}-d, the query {}-d", m.dim, unit_query.size()));
  // Lists ranked by centroid similarity: all of them (a few hundred inner products), so that more
  // can be taken while the first ones hold too few cells.
  const std::size_t lists = m.stats.lists;
  const Eigen::VectorXf similarity =
      m.centroid_rows * Eigen::Map<const Eigen::VectorXf>(unit_query.data(), static_cast<Eigen::Index>(m.dim));
  std::vector<uint32_t> order(lists);
  for (std::size_t l = 0; l < lists; ++l) order[l] = static_cast<uint32_t>(l);
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return similarity[a] != similarity[b] ? similarity[a] > similarity[b] : a < b;
  });
  const std::size_t wanted = std::min(probes ? probes : m.stats.probes, lists);
  const std::size_t keep = std::max({m.rerank_factor * top_k, m.rerank_min, std::size_t{1}});
  const std::size_t shortlist = m.refine_factor * keep;
  // The probed lists' coarse planes stream from memory; the best `shortlist` cells by coarse score
  // are kept in a buffer of twice that, cut back whenever full (the cut's score bars later cells).
  // A cell's approximate score is its list's centroid similarity plus its residual's (codes of the
  // residuals: the constant part of the decoded value is the same for every cell and left out).
  const std::size_t bytes = m.codebooks[0].plane_bytes();
  struct Kept {
    float score;
    uint32_t slot;  // in the list arrays
    uint32_t rank;  // of its list in `order`
  };
  const auto ahead = [](const Kept& a, const Kept& b) { return a.score != b.score ? a.score > b.score : a.slot < b.slot; };
  std::vector<Kept> best;
  best.reserve(2 * shortlist);
  float bar = -std::numeric_limits<float>::infinity();
  const auto cut = [&](std::size_t to) {
    std::nth_element(best.begin(), best.begin() + static_cast<std::ptrdiff_t>(to - 1), best.end(), ahead);
    best.resize(to);
    bar = best[to - 1].score;
  };
  std::vector<ann_codes::QueryWeights> weights;  // of the lists looked at, by rank
  constexpr std::size_t kChunk = 512;
  int32_t scores[kChunk];
  std::size_t count = 0, scored = 0;
  for (std::size_t r = 0; r < lists && (r < wanted || count < top_k); ++r) {
    deadline.check("scanning the ANN index's lists");
    const std::size_t l = order[r], begin = m.list_begin[l], end = m.list_begin[l + 1];
    count += end - begin;
    const float base = similarity[static_cast<Eigen::Index>(l)];
    const ann_codes::QueryWeights& w = weights.emplace_back(m.codebooks[l].weights(unit_query.data()));
    // The largest coarse score a cell of this list can get: below the bar, none of its cells would
    // be kept, so its codes are not read (the answer is the same).
    if (base + w.coarse_most < bar) continue;
    scored += end - begin;
    for (std::size_t c = begin; c < end; c += kChunk) {
      const std::size_t k = std::min(kChunk, end - c);
      ann_codes::score_nibbles(m.coarse.data() + c * bytes, k, bytes, w.coarse.data(), scores);
      for (std::size_t j = 0; j < k; ++j) {
        const float score = base + (w.coarse_offset + w.coarse_unit * static_cast<float>(scores[j]));
        if (score < bar) continue;
        best.push_back({score, static_cast<uint32_t>(c + j), static_cast<uint32_t>(r)});
        if (best.size() == 2 * shortlist) cut(shortlist);
      }
    }
  }
  if (best.size() > shortlist) cut(shortlist);
  // The shortlist ordered by the whole 8-bit codes (the fine plane joined to the coarse one).
  // The shortlist's fine planes are read at random: the planes a few places ahead are fetched
  // while this one is scored (the join otherwise waits on a cache miss per line).
  std::vector<uint8_t> code(2 * bytes);
  constexpr std::size_t kAhead = 4;
  const auto fetch = [&](std::size_t i) {
    if (i >= best.size()) return;
    const std::size_t at = std::size_t{best[i].slot} * bytes;
    for (std::size_t b = 0; b < bytes; b += 64) {
      __builtin_prefetch(m.coarse.data() + at + b);
      __builtin_prefetch(m.fine.data() + at + b);
    }
  };
  for (std::size_t i = 0; i < kAhead; ++i) fetch(i);
  for (std::size_t i = 0; i < best.size(); ++i) {
    fetch(i + kAhead);
    Kept& k = best[i];
    ann_codes::join_planes(m.coarse.data() + std::size_t{k.slot} * bytes, m.fine.data() + std::size_t{k.slot} * bytes,
                           bytes, code.data());
    const ann_codes::QueryWeights& w = weights[k.rank];
    int32_t fine = 0;
    ann_codes::score_codes(code.data(), 1, 2 * bytes, w.fine.data(), &fine);
    k.score = similarity[static_cast<Eigen::Index>(order[k.rank])] + (w.fine_offset + w.fine_unit * static_cast<float>(fine));
  }
  if (best.size() > keep) cut(keep);
  if (scanned) *scanned = scored;
  std::vector<std::size_t> out;
  out.reserve(best.size());
  for (const Kept& k : best) out.push_back(m.positions[k.slot]);
  std::sort(out.begin(), out.end());
  return out;
}

std::size_t AnnIndex::index_size() const { return impl_->index_size; }

AnnIndexStats AnnIndex::stats() const { return impl_->stats; }

}  // namespace slamvdb
