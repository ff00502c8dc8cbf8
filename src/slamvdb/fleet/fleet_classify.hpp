#pragma once
// `classify --db`: every semantic cell of a region of the fleet map classified, tile by tile, so
// memory holds one tile's submaps whatever the region's size (docs/fleet-design.md, "Classify").
// No summary prunes a classification: every cell of the region is an answer (its class is an
// argmax over the query set, which no bound can skip without knowing it), so the pruning is the
// region's: PostGIS's look-up, then each submap's box against the region's exact shape (a --near
// ball or cylinder inside its bounding box) and submaps without semantic voxels, never read.
#include <cstddef>
#include <string>
#include <vector>

#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/query/query_region.hpp"

namespace slamvdb::fleet {

struct FleetClassifyOptions {
  ClassifyOptions classify{};
  ModelIdCheck model_check = ModelIdCheck::kRequireMatch;
  std::vector<std::string> sessions{};  // empty: every session
  // Square tiles of the fleet frame's xy plane (metres, rounded to whole index cells): one tile's
  // submaps are in memory at a time; a submap that meets several tiles is read once per tile.
  double tile_side = 100.0;
};

struct FleetClassification {
  std::vector<ClassifiedCell> cells;  // in sort_by_cell order
  std::size_t submaps_in_region = 0;  // footprints meeting the region's bounding box (PostGIS)
  std::size_t submaps_read = 0;       // of those, read (at least once)
  std::size_t submaps_skipped = 0;    // never read: outside the region's shape, or no semantic voxel
  std::size_t reads = 0;              // submap reads over all tiles
  std::size_t tiles = 0;              // tiles that held submaps
  std::size_t peak_submaps_in_memory = 0;
  double seconds = 0;
};

// The same cells, classes and scores as classify_region on the pulled region (`region`'s
// bounds): each cell lies in one tile and is classified from every submap that can put an entry in
// it (those whose box comes within one index cell of the tile).
FleetClassification classify_fleet_region(FleetDatabase& fleet, const QueryRegion& region, const QuerySet& queries,
                                          const FleetClassifyOptions& options = {});

}  // namespace slamvdb::fleet
