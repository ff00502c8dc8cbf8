// `slamvdb pull`: a region of a fleet map (PostgreSQL + PostGIS, issue 24) as a normal map file:
// every session's submaps whose footprint meets the region, in the fleet frame, written one
// submap at a time (memory: one submap) into a file that replaces its target only when complete.
#include <fmt/format.h>

#include <memory>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "progress.hpp"
#include "region_options.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/fleet/fleet_database.hpp"
#include "option_checks.hpp"
#include "slamvdb/store/map_file_writer.hpp"

namespace slamvdb::cli::cmd_pull {
namespace {

struct Options {
  std::string db, output;
  std::vector<std::string> sessions;
  RegionOptions region;
};

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "pull", "Write a region of a fleet map (PostgreSQL + PostGIS) as a map file: every session's submaps whose "
              "footprint meets the region, whole, anchored in the fleet frame; payloads checked row by row");
  cmd->add_option("--db", opt->db,
                  "The fleet database: a libpq connection string (postgresql://user@host/db or key=value); "
                  "passwords from PGPASSFILE / ~/.pgpass or PGPASSWORD, never on the command line")
      ->required();
  cmd->add_option("-o,--output", opt->output, "Map file to write (.svdb; replaced only when complete)")->required();
  opt->region.add_to(cmd, "submaps");
  cmd->add_option("--session", opt->sessions, "Only these sessions (repeatable; default: every session)");
  auto io = std::make_shared<IoOptions>(cmd);
  io->output("-o", opt->output, {}, /*lock=*/true);
  cmd->callback([opt, io] {
    const std::optional<QueryRegion> region = opt->region.region();  // usage errors first (exit 2)
    if (!region) usage_error("pull needs a region: --bbox, or --near with --radius");
    io->check();
    fleet::FleetDatabase fleet(opt->db);
    fleet::FleetDefinition definition = fleet.definition();
    MapInfo info = definition.info;
    info.source = fmt::format("fleet map {}, region {}{}", fleet.display_url(),
                              !opt->region.bbox.empty() ? "--bbox " + opt->region.bbox
                                                        : fmt::format("--near {} --radius {}", opt->region.near,
                                                                      opt->region.radius),
                              opt->sessions.empty() ? "" : ", sessions " + fmt::format("{}", fmt::join(opt->sessions, ", ")));
    // All or nothing: the map grows submap by submap in the output's temporary sibling, which
    // replaces the target only once every submap is in (a failed pull leaves the target as it was).
    OutputFile output(opt->output);
    auto writer = MapFileWriter::create(output.temp_path(), definition.params, info);
    SemanticMap scratch(definition.params, info);  // holds one submap at a time for the writer
    ProgressBar bar("pull", 0, "submaps");
    std::size_t done = 0;
    info.sessions.clear();  // the fleet's sessions, as the submaps come (assign_pulled_session)
    const fleet::PullReport r = fleet.pull({region->bounds(), opt->sessions}, [&](fleet::PulledSubmap&& s) {
      fleet::assign_pulled_session(info, s);
      const int id = s.info.id;
      scratch.add_finished_submap(s.info, std::move(s.voxels));
      writer->save_finished(scratch, id);
      scratch.remove_finished_submap(id);
      bar.update(++done);
    });
    const MapFileSummary written = writer->finish(info, 0);
    writer.reset();
    output.commit();
    bar.finish();
    fmt::print("pulled     {} submaps of {} session{} ({}) into {}\n", r.submaps, r.sessions.size(),
               r.sessions.size() == 1 ? "" : "s", fmt::join(r.sessions, ", "), opt->output);
    fmt::print("read       {} payload rows, {:.1f} MB in {:.2f} s; the file holds {} known, {} occupied, {} semantic "
               "voxels\n",
               r.rows, static_cast<double>(r.payload_bytes) / 1e6, r.seconds, written.known_voxels,
               written.occupied_voxels, written.semantic_voxels);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_pull
