// `slamvdb push`: a map file's submaps into a fleet map (PostgreSQL + PostGIS, issue 24) as one
// session: one transaction per submap, idempotent, refused before any write when the map's
// embedding space, voxel size or ontology differ from the fleet's.
#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "command_registry.hpp"
#include "progress.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/point_text.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "slamvdb/store/map_store.hpp"

namespace slamvdb::cli::cmd_push {
namespace {

struct Options {
  std::string map, db, session, robot, fleet_pose;
  bool json = false;
};

// "x,y,z,yaw" (metres, degrees): where the session's world frame lies in the fleet frame.
Pose parse_fleet_pose(const std::string& text) {
  const std::vector<double> v = parse_numbers(text, "--fleet-pose", 4, 4, "x,y,z,yaw");
  Pose T = Pose::Identity();
  T.linear() = Eigen::AngleAxisd(v[3] * M_PI / 180.0, Vec3d::UnitZ()).toRotationMatrix();
  T.translation() = Vec3d(v[0], v[1], v[2]);
  return T;
}

nlohmann::json report_json(const fleet::PushReport& r, const std::string& session, const std::string& db) {
  return {{"database", db},
          {"session", session},
          {"session_id", r.session_id},
          {"session_created", r.session_created},
          {"submaps_added", r.submaps_added},
          {"submaps_unchanged", r.submaps_unchanged},
          {"anchors_moved", r.anchors_moved},
          {"payloads_replaced", r.payloads_replaced},
          {"rows_written", r.rows_written},
          {"payload_bytes", r.payload_bytes},
          {"seconds", r.seconds}};
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "push", "Push a map file's submaps into a fleet map (PostgreSQL + PostGIS) as one session: one transaction per "
              "submap, repeated pushes write only what changed (a moved anchor rewrites the catalog row only)");
  cmd->add_option("map", opt->map, "Map file (.svdb)")->required()->check(CLI::ExistingFile);
  cmd->add_option("--db", opt->db,
                  "The fleet database: a libpq connection string (postgresql://user@host/db or key=value); "
                  "passwords from PGPASSFILE / ~/.pgpass or PGPASSWORD, never on the command line. An empty "
                  "database gets PostGIS and the schema")
      ->required();
  cmd->add_option("--session", opt->session, "The session's name in the fleet (default: the map file's name)");
  cmd->add_option("--robot", opt->robot, "Which robot drove it (free text)");
  cmd->add_option("--fleet-pose", opt->fleet_pose,
                  "x,y,z,yaw (m, degrees): where this session's world frame lies in the fleet frame (from `align` "
                  "or a prior); default: the fleet frame itself");
  cmd->add_flag("--json", opt->json, "Print the report as JSON");
  cmd->callback([opt] {
    // Usage checked before any work (exit 2).
    fleet::PushOptions push;
    push.session = opt->session.empty() ? std::filesystem::path(opt->map).stem().string() : opt->session;
    push.robot = opt->robot;
    if (!opt->fleet_pose.empty()) {
      try {
        push.T_fleet_session = parse_fleet_pose(opt->fleet_pose);
      } catch (const Error& e) {
        throw CLI::ValidationError(e.what());
      }
    }
    // A wrong URL or a map the fleet cannot take fails here, before the voxels are read.
    fleet::FleetDatabase fleet(opt->db);
    const MapFileSummary summary = read_map_summary(opt->map);
    fleet.check_map(summary.params, summary.info);
    const SemanticMap map = load_map(opt->map);
    ProgressBar bar("push", map.num_submaps(), "submaps");
    push.on_submap = [&](std::size_t done, std::size_t) { bar.update(done); };
    const fleet::PushReport r = fleet.push_map(map, push);
    bar.finish();
    if (opt->json) {
      fmt::print("{}\n", report_json(r, push.session, fleet.display_url()).dump(2));
      return;
    }
    fmt::print("pushed     {} to {} as session '{}' ({})\n", opt->map, fleet.display_url(), push.session,
               r.session_created ? "new" : "existing");
    fmt::print("submaps    {} added, {} unchanged, {} anchors moved, {} payloads replaced\n", r.submaps_added,
               r.submaps_unchanged, r.anchors_moved, r.payloads_replaced);
    fmt::print("written    {} payload rows, {:.1f} MB in {:.2f} s ({:.1f} MB/s)\n", r.rows_written,
               static_cast<double>(r.payload_bytes) / 1e6, r.seconds,
               r.seconds > 0 ? static_cast<double>(r.payload_bytes) / 1e6 / r.seconds : 0.0);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_push
