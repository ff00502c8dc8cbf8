#pragma once
// A similarity search over a region of the fleet map that reads only the submaps that can hold an
// answer (docs/fleet-design.md, "Summaries"): the region's submaps are grouped so that no index
// cell spans two groups, each group's summaries bound the best cosine any of its cells can score,
// and a group whose bound cannot enter the current top-k (or reach the threshold) is never read.
#include <cstddef>
#include <span>

#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/query/map_query.hpp"

namespace slamvdb::fleet {

struct PrunedSearchReport {
  std::size_t submaps_in_region = 0;
  std::size_t submaps_scored = 0;   // read from the database
  std::size_t submaps_skipped = 0;  // never read: their group's bound was below the top-k or threshold
  std::size_t groups = 0;           // sets of submaps that may share index cells
  std::size_t groups_skipped = 0;
  double seconds = 0;
};

struct PrunedRegion {
  SemanticMap map;  // the scored submaps only (the fleet's parameters)
  PrunedSearchReport report;
};

// The region's submaps that can hold an answer of `similarity_search(pulled region, query,
// options)`, as one map: the same search on it gives exactly the answer on the whole pulled
// region (the same cells, scores and order). Groups are read best bound first, one at a time
// (memory while deciding: one group), then the kept submaps once more into the returned map.
PrunedRegion pull_for_search(FleetDatabase& fleet, const PullRequest& request, std::span<const float> query,
                             const SearchOptions& options);

}  // namespace slamvdb::fleet
