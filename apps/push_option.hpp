#pragma once
// `--push URL [--push-session NAME]` on `map` and `slam`: each finished submap goes to a fleet map
// (PostgreSQL + PostGIS) as it finishes, through the checkpoint path (fleet/fleet_live_push.hpp).
#include <CLI/CLI.hpp>
#include <fmt/format.h>

#include <filesystem>
#include <memory>
#include <string>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fleet/fleet_live_push.hpp"

namespace slamvdb::cli {

struct PushOption {
  std::string url, session;

  // Not configurable (as --serve): the map written is the same with or without them, so a config
  // file and the map's recorded config do not carry a fleet's address.
  void add_to(CLI::App* cmd) {
    const auto fleet = [](CLI::Option* o) { return o->configurable(false)->group("Fleet (--push)"); };
    fleet(cmd->add_option("--push", url,
                    "Also push each finished submap into this fleet map as it finishes (a libpq connection string; "
                    "passwords from PGPASSFILE / ~/.pgpass or PGPASSWORD): one transaction per submap, loop "
                    "corrections as anchor updates; checked before mapping. The map file is written first: a push "
                    "failure stops pushing, not mapping, and the run ends with exit 1 and a complete map file "
                    "(`slamvdb push` it to complete the fleet)"));
    fleet(cmd->add_option("--push-session", session, "The session's name in the fleet (default: the map file's name)"));
  }

  // Connects, checks the map against the fleet and creates the session, before mapping starts
  // (null without --push).
  std::unique_ptr<fleet::FleetPushingStore> connect(const MapParams& params, const MapInfo& info,
                                                    const std::string& output) const {
    if (url.empty()) return nullptr;
    fleet::PushOptions options;
    options.session = session.empty() ? std::filesystem::path(output).stem().string() : session;
    return std::make_unique<fleet::FleetPushingStore>(url, params, info, options);
  }
};

// After the map file is complete: the session's final source, what was pushed, and a failure as an
// Error (exit 1) that says the file is complete and how to finish the push.
inline void finish_push(fleet::FleetPushingStore* push, const PushOption& option, const MapInfo& final_info,
                        const std::string& output) {
  if (!push) return;
  push->set_source(final_info.source);
  const fleet::PushReport& r = push->report();
  fmt::print("fleet: {} submaps added, {} unchanged, {} anchors moved, {} payloads replaced, {} removed (merged) to {} "
             "as session id {} ({:.1f} MB, {:.2f} s in pushes)\n",
             r.submaps_added, r.submaps_unchanged, r.anchors_moved, r.payloads_replaced, r.submaps_removed,
             push->display_url(), r.session_id, static_cast<double>(r.payload_bytes) / 1e6, r.seconds);
  if (!push->error().empty())
    throw Error(fmt::format("pushing to the fleet stopped: {}; the map file {} is complete: `slamvdb push {} --db URL "
                            "--session {}` pushes what the fleet lacks",
                            push->error(), output, output,
                            option.session.empty() ? std::filesystem::path(output).stem().string() : option.session));
}

}  // namespace slamvdb::cli
