#pragma once
// The fleet catalog's rows decoded from the text PostgreSQL gives them in (FleetDatabase::catalog
// and region_catalog read their columns as text and hand them here): a damaged or foreign row is
// an Error naming the row and the column, never another exception, a NaN or an empty box. No
// database here, so fuzz/fuzz_fleet_catalog_rows.cpp feeds them any bytes.
#include <optional>
#include <string_view>
#include <vector>

#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/fleet/fleet_pull.hpp"

namespace slamvdb::fleet {

// One row as text, one entry per column in the statement's order; std::nullopt for NULL.
using TextRow = std::vector<std::optional<std::string_view>>;

// slamvdb.sessions rows (id, name, robot, source, time_begin, time_end, t_fleet_session) and
// slamvdb.submaps rows (session, submap, t_world_submap, time_begin, time_end, path_length, blocks,
// known_voxels, occupied_voxels, semantic_voxels, revision, x_min, y_min, z_min, x_max, y_max,
// z_max of the footprint) as the catalog: each submap under the session its first column names,
// anchored in the fleet frame (T_fleet_session * T_world_submap), counted in its session. A
// submap of no session (the foreign key makes it impossible on one server) is counted in
// FleetCatalog::submaps_without_session and left out; a session id given twice is an Error.
inline constexpr std::size_t kCatalogSessionColumns = 7;
inline constexpr std::size_t kCatalogSubmapColumns = 17;
FleetCatalog catalog_of(const std::vector<TextRow>& sessions, const std::vector<TextRow>& submaps);

// A row of region_catalog: session, submap, x_min, y_min, z_min, x_max, y_max, z_max,
// embedding_centroid (real[] or NULL), embedding_radius (or NULL: no summary), semantic_voxels.
inline constexpr std::size_t kRegionSubmapColumns = 11;
RegionSubmap region_submap_of(const TextRow& row);

}  // namespace slamvdb::fleet
