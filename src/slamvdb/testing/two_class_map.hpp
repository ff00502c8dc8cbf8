#pragma once
// For tests of the commands that read a map and a query set (export, classify, query): a small map
// on disk and a query set for it. Ground (z = 0, 8 x 8 m) seen by one scan from (0, 0, 1.5);
// semantics on the ground: class 0 where x < 0, class 1 where x >= 0, as embeddings e0 / e1 in a
// 4-d space "test-space"; the query set's vectors are e0 and e1.
#include <string>
#include <utility>

#include "slamvdb/query/query_set.hpp"
#include "slamvdb/store/map_store.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb::testing {

struct TwoClassMap {
  TempDir tmp;
  std::filesystem::path map = tmp.path / "m.svdb", queries = tmp.path / "q.json";
  std::size_t semantic_cells = 0;

  // `names`: the query set's class names for x < 0 and x >= 0.
  explicit TwoClassMap(std::pair<std::string, std::string> names = {"smooth", "rough"}) {
    MapParams params;
    params.semantic.dim = 4;
    params.submap_length = 0;
    MapInfo info;
    info.model_id = "test-space";
    info.source = "test";
    SemanticMap m(params, info);
    std::vector<Vec3f> points;
    for (float x = -4; x <= 4; x += 0.1f)
      for (float y = -4; y <= 4; y += 0.1f) points.emplace_back(x, y, -1.49f);
    Pose T = Pose::Identity();
    T.translation() = Vec3d(0, 0, 1.5);
    m.integrate_scan(0.0, points, T);
    m.update_active(0.0, [](VoxelMap& v, const Pose& T_world_submap, std::span<const PlacedVoxelMap>) {
      v.occupancy().for_each_occupied([&](const VoxelKey& k, float) {
        const double x = (T_world_submap * center_of_key(k, 0.25)).x();
        const float e[4] = {x < 0 ? 1.f : 0.f, x < 0 ? 0.f : 1.f, 0, 0};
        v.semantics().integrate(k, e);
      });
    });
    m.finish_active_submap();
    save_map(map, m);
    semantic_cells = m.num_index_cells();
    QuerySet q;
    q.model_id = "test-space";
    q.names = {names.first, names.second};
    q.vectors = QueryMatrix::Zero(2, 4);
    q.vectors(0, 0) = q.vectors(1, 1) = 1;
    save_query_set(queries, q);
  }
  // The CLI with `args`, stdout and stderr together.
  std::string cli(const std::string& args) const { return shell_quote(SLAMVDB_CLI_PATH) + " " + args + " 2>&1"; }
  std::string out(const std::string& name) const { return shell_quote((tmp.path / name).string()); }
};

}  // namespace slamvdb::testing
