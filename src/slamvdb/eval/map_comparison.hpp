#pragma once
// Agreement of two maps' geometry, read through their world occupancy (every submap at its
// current anchor): how close a map built from estimated poses is to one from ground truth.
#include <vector>

#include "slamvdb/map/keys.hpp"
#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

// Occupied world cells of both maps: |A and B| / |A or B|. With tolerance t, a cell of one map
// counts as shared when the other has an occupied cell within t cells of it on every axis (two
// correct maps whose submaps start at other places already differ by resampling onto the world
// grid, so t = 1 is the fair comparison); the shared count is the mean of both directions.
double occupied_iou(const SemanticMap& a, const SemanticMap& b, int tolerance = 0);

// The same on occupied cells read once: a map's occupied world cells, sorted. Reading them
// resamples every known voxel of every submap onto the world grid, the costly part (about 10 s
// for a 60 m drive under ASan), so a map compared several times (at two tolerances, or with
// several others) is read once.
using OccupiedCells = std::vector<IndexCellKey>;
OccupiedCells occupied_world_cells(const SemanticMap& m);
double occupied_iou(const OccupiedCells& a, const OccupiedCells& b, int tolerance = 0);

}  // namespace slamvdb
