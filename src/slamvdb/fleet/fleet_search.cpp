#include "slamvdb/fleet/fleet_search.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <numeric>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_connection.hpp"

namespace slamvdb::fleet {
namespace {

// Groups of submaps no index cell spans: two submaps whose boxes come within one index cell of
// each other may bin entries into the same cell, so they are joined (union-find; a region holds
// hundreds of submaps, so all pairs are cheap).
std::vector<std::vector<std::size_t>> search_groups(const std::vector<RegionSubmap>& submaps, double cell) {
  std::vector<std::size_t> parent(submaps.size());
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  const auto root = [&](std::size_t i) {
    while (parent[i] != i) i = parent[i] = parent[parent[i]];
    return i;
  };
  for (std::size_t i = 0; i < submaps.size(); ++i) {
    Eigen::AlignedBox3d grown = submaps[i].bounds_fleet;
    grown.min().array() -= cell;
    grown.max().array() += cell;
    for (std::size_t j = i + 1; j < submaps.size(); ++j)
      if (grown.intersects(submaps[j].bounds_fleet)) parent[root(j)] = root(i);
  }
  std::vector<std::vector<std::size_t>> groups;
  std::vector<std::ptrdiff_t> group_of(submaps.size(), -1);
  for (std::size_t i = 0; i < submaps.size(); ++i) {
    std::ptrdiff_t& g = group_of[root(i)];
    if (g < 0) g = static_cast<std::ptrdiff_t>(groups.size()), groups.emplace_back();
    groups[static_cast<std::size_t>(g)].push_back(i);
  }
  return groups;
}

}  // namespace

std::vector<RegionSubmap> FleetDatabase::region_catalog(const PullRequest& request) {
  std::vector<RegionSubmap> out;
  try {
    pqxx::read_transaction tx(connection_->connection);
    const Eigen::AlignedBox3d& b = request.box_fleet;
    const std::string names = text_array(request.sessions);
    for (const pqxx::row& row : tx.exec_params(
             "SELECT m.session, m.submap, ST_XMin(m.footprint), ST_YMin(m.footprint), m.z_min, ST_XMax(m.footprint), "
             "ST_YMax(m.footprint), m.z_max, m.embedding_centroid::text, m.embedding_radius, m.semantic_voxels "
             "FROM slamvdb.submaps m JOIN slamvdb.sessions s ON s.id = m.session "
             "WHERE m.shard = ANY($9::integer[]) AND m.footprint && ST_MakeEnvelope($1, $2, $3, $4, 0) "
             "AND m.z_max >= $5 AND m.z_min <= $6 AND ($7 OR s.name = ANY($8::text[])) ORDER BY s.id, m.submap",
             b.min().x(), b.min().y(), b.max().x(), b.max().y(), b.min().z(), b.max().z(), request.sessions.empty(),
             names, region_shards(tx, b))) {
      try {
        out.push_back(region_submap_of(text_row(row)));  // fleet_catalog_rows.hpp
      } catch (const Error& e) {
        throw FleetDataError(fmt::format("fleet database {}: {}", display_url_, e.what()));
      }
    }
  } catch (const pqxx::failure& e) {
    throw database_error(fmt::format("fleet database {}", display_url_), e);
  }
  return out;
}

PrunedRegion pull_for_search(FleetDatabase& fleet, const PullRequest& request, std::span<const float> query,
                             const SearchOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  const FleetDefinition definition = fleet.definition();
  MapInfo info = definition.info;
  info.source = fmt::format("fleet map {}", fleet.display_url());
  PrunedRegion out{SemanticMap(definition.params, info), {}};
  const std::vector<RegionSubmap> submaps = fleet.region_catalog(request);
  const std::vector<std::vector<std::size_t>> groups = search_groups(submaps, definition.params.index_cell());
  out.report.submaps_in_region = submaps.size();
  out.report.groups = groups.size();
  if (submaps.empty()) return out;
  if (!options.top_k && !(options.threshold > -1.0f)) {  // nothing can be skipped: one read of the region
    fleet.pull(request, [&](PulledSubmap&& s) { out.map.add_finished_submap(s.info, std::move(s.voxels)); });
    out.report.submaps_scored = submaps.size();
    out.report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
  }
  Eigen::VectorXf q = Eigen::Map<const Eigen::VectorXf>(query.data(), static_cast<Eigen::Index>(query.size()));
  if (!(q.norm() > 0) || !q.allFinite()) throw Error("the query vector is zero or not finite");
  q.normalize();

  // Each group's bound: its members' caps enclosed (a member without a summary: no bound).
  std::vector<double> bound(groups.size(), 1.0);
  for (std::size_t g = 0; g < groups.size(); ++g) {
    std::vector<EmbeddingCap> caps;
    for (const std::size_t i : groups[g])
      if (submaps[i].cap) caps.push_back(*submaps[i].cap);
    if (caps.size() != groups[g].size()) continue;
    if (const std::optional<EmbeddingCap> cap = enclosing_cap(caps)) bound[g] = cap_cosine_bound(*cap, q);
  }
  std::vector<std::size_t> order(groups.size());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::stable_sort(order.begin(), order.end(), [&](std::size_t a, std::size_t b) { return bound[a] > bound[b]; });

  std::vector<float> best;  // the best scores so far, at most top_k, descending
  std::vector<FleetSubmapKey> kept;
  for (const std::size_t g : order) {
    const bool below_top_k = options.top_k && best.size() >= options.top_k && bound[g] < best.back();
    if (bound[g] < options.threshold || below_top_k) {
      ++out.report.groups_skipped;
      out.report.submaps_skipped += groups[g].size();
      continue;
    }
    PullRequest one = request;
    one.only.emplace();
    for (const std::size_t i : groups[g]) one.only->push_back(submaps[i].key);
    SemanticMap group(definition.params, info);
    fleet.pull(one, [&](PulledSubmap&& s) { group.add_finished_submap(s.info, std::move(s.voxels)); });
    // No index cell is shared with another group, so the group's cells score as in the whole region.
    for (const ScoredCell& c : similarity_search(group, query, options)) best.push_back(c.score);
    std::sort(best.begin(), best.end(), std::greater<>());
    if (options.top_k && best.size() > options.top_k) best.resize(options.top_k);
    kept.insert(kept.end(), one.only->begin(), one.only->end());
    out.report.submaps_scored += groups[g].size();
  }
  if (!kept.empty()) {
    std::sort(kept.begin(), kept.end());
    PullRequest scored = request;
    scored.only = kept;
    fleet.pull(scored, [&](PulledSubmap&& s) { out.map.add_finished_submap(s.info, std::move(s.voxels)); });
  }
  out.report.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  return out;
}

}  // namespace slamvdb::fleet
