#pragma once
// GET /api/events: Server-Sent Events that tell a viewer when the map changed (a counter that
// grows with every finished, moved or merged submap: MapService::changes()), so a page can reload
// its points without polling. A saved map never changes: its stream says so once, then sends a
// heartbeat comment. Live mode (`map|slam --serve`, live_map_service.hpp) bumps the counter and
// sends before each "map" event what changed ("submaps" events), and "progress" events as scans
// are mapped (formats: docs/serve-design.md "Live mode", docs/openapi.yaml). Each stream holds one
// worker thread of the server for its life, so at most `max_streams` are open (more: 503).
#include <atomic>
#include <cstdint>
#include <string>

#include "slamvdb/server/map_service.hpp"

namespace httplib {
struct Response;
}

namespace slamvdb {

struct EventStreamOptions {
  std::size_t max_streams = 4;
  // A comment line when nothing else was sent: keeps proxies from timing out, and is how a stream
  // notices a client that left (only a failed write tells), so it is short: a stream outlives its
  // client by two heartbeats at most.
  double heartbeat_seconds = 2.0;
  double poll_seconds = 0.2;        // how often a stream looks at the counter
};

// One event: "id: N\nevent: map\ndata: {\"changes\": N, \"submaps\": S, \"semantic_cells\": C}\n\n".
std::string map_event_text(const MapService& map, std::uint64_t changes);

class MapEventStreams {
 public:
  // `stopping`: set when the server stops; every open stream then ends within poll_seconds.
  MapEventStreams(const MapService& map, const std::atomic<bool>& stopping, EventStreamOptions options = {});
  // Makes `res` an event stream (text/event-stream): the current counter at once (with "retry:"),
  // then an event whenever it changes and a heartbeat otherwise, until the client leaves or the
  // server stops. Throws RequestError 503 (with Retry-After) when max_streams streams are open.
  void open(httplib::Response& res);
  std::size_t open_streams() const { return open_.load(); }

 private:
  const MapService& map_;
  const std::atomic<bool>& stopping_;
  EventStreamOptions options_;
  std::atomic<std::size_t> open_{0};
};

}  // namespace slamvdb
