#include "slamvdb/query/ann_index.hpp"

#include <faiss/Clustering.h>
#include <faiss/IndexFlat.h>
#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Core>

#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdint>

#include "slamvdb/core/embedding_kernels.hpp"
#include "slamvdb/core/error.hpp"

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
  std::unique_ptr<faiss::IndexFlatIP> centroids;  // for the build's batched assignment
  Eigen::MatrixXf centroid_rows;                  // lists x dim: a question's similarities, without OpenMP
  std::vector<std::vector<uint32_t>> lists;  // cell positions of each list, ascending
  std::size_t index_size = 0;
  AnnIndexStats stats;
};

AnnIndex::AnnIndex(const SemanticMap& map, const AnnOptions& options) : impl_(std::make_unique<Impl>()) {
  using namespace ann_index_detail;
  const auto start = std::chrono::steady_clock::now();
  const auto dim = static_cast<std::size_t>(map.params().semantic.dim);
  Impl& m = *impl_;
  m.dim = dim;
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
    const std::size_t sample_target = std::min(std::max<std::size_t>(options.training_cells, 1), n);
    std::vector<std::size_t> positions;
    for (std::size_t s = 0; s < sample_target; ++s) positions.push_back(s * n / sample_target);
    decode_batch(positions);
    std::vector<float> training;
    for (std::size_t j = 0; j < positions.size(); ++j)
      if (valid[j]) training.insert(training.end(), batch.begin() + static_cast<std::ptrdiff_t>(j * dim),
                                    batch.begin() + static_cast<std::ptrdiff_t>((j + 1) * dim));
    const std::size_t sample = training.size() / dim;
    if (sample == 0) throw Error("the map has no semantic cell with a non-zero embedding to index");
    const std::size_t lists = std::min(options.lists ? options.lists : default_lists(n), sample);
    faiss::ClusteringParameters params;
    params.niter = options.iterations;
    params.spherical = true;  // centroids on the unit sphere: inner product is cosine
    params.seed = 1234;
    params.max_points_per_centroid = static_cast<int>(sample / lists + 1);
    params.min_points_per_centroid = 1;
    faiss::Clustering clustering(static_cast<int>(dim), lists, params);
    m.centroids = std::make_unique<faiss::IndexFlatIP>(static_cast<ann_index_detail::FaissId>(dim));
    clustering.train(static_cast<ann_index_detail::FaissId>(sample), training.data(), *m.centroids);
    training = {};
    m.centroid_rows = Eigen::Map<const Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>>(
        m.centroids->get_xb(), static_cast<Eigen::Index>(lists), static_cast<Eigen::Index>(dim));
    // Each cell into the list of its most similar centroid (faiss batches this with BLAS).
    std::vector<float> distance;
    std::vector<ann_index_detail::FaissId> label;
    m.lists.assign(lists, {});
    constexpr std::size_t kBatch = 16384;
    for (std::size_t b = 0; b < n; b += kBatch) {
      const std::size_t k = std::min(kBatch, n - b);
      positions.resize(k);
      for (std::size_t j = 0; j < k; ++j) positions[j] = b + j;
      decode_batch(positions);
      distance.resize(k);
      label.resize(k);
      m.centroids->search(static_cast<ann_index_detail::FaissId>(k), batch.data(), 1, distance.data(), label.data());
      for (std::size_t j = 0; j < k; ++j) {
        if (!valid[j] || label[j] < 0) continue;
        m.lists[static_cast<std::size_t>(label[j])].push_back(static_cast<uint32_t>(b + j));
        ++m.stats.cells;
      }
    }
    m.stats.lists = lists;
  });
  m.centroids.reset();  // faiss's copy; its OpenMP search is not wanted on request threads
  m.stats.probes = options.probes ? std::min(options.probes, m.stats.lists) : std::max<std::size_t>(1, m.stats.lists / 8);
  m.stats.memory_bytes = m.stats.lists * dim * sizeof(float) + m.stats.cells * sizeof(uint32_t) +
                         m.stats.lists * sizeof(std::vector<uint32_t>);
  m.stats.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

AnnIndex::~AnnIndex() = default;

std::vector<std::size_t> AnnIndex::candidates(std::span<const float> unit_query, std::size_t probes,
                                              std::size_t min_cells) const {
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
  // The lists' cells marked in a bitmap and given back in ascending position: read in the order the
  // global index holds them, a cell's record and embedding are far more often in cache or in an
  // open memory page than in list order (which jumps across the whole map for every cell).
  std::vector<uint64_t> marked((m.index_size + 63) / 64, 0);
  std::size_t count = 0;
  for (std::size_t r = 0; r < lists && (r < wanted || count < min_cells); ++r) {
    for (const uint32_t i : m.lists[order[r]]) marked[i >> 6] |= uint64_t{1} << (i & 63);
    count += m.lists[order[r]].size();
  }
  std::vector<std::size_t> out;
  out.reserve(count);
  for (std::size_t w = 0; w < marked.size(); ++w)
    for (uint64_t bits = marked[w]; bits; bits &= bits - 1)
      out.push_back(w * 64 + static_cast<std::size_t>(std::countr_zero(bits)));
  return out;
}

std::size_t AnnIndex::index_size() const { return impl_->index_size; }

AnnIndexStats AnnIndex::stats() const { return impl_->stats; }

}  // namespace slamvdb
