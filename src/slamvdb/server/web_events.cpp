#include "slamvdb/server/web_events.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <optional>
#include <thread>

#include "slamvdb/server/httplib_include.hpp"
#include "slamvdb/server/request_decoding.hpp"

namespace slamvdb {

std::string map_event_text(const MapService& map, std::uint64_t changes) {
  const nlohmann::json info = map.info();
  const nlohmann::json data = {{"changes", changes},
                               {"submaps", info.contains("submaps") ? info["submaps"].size() : 0},
                               {"semantic_cells", map.semantic_cells()}};
  return fmt::format("id: {}\nevent: map\ndata: {}\n\n", changes, data.dump());
}

namespace {

// A live-mode event ("submaps" or "progress"), its data one JSON line.
std::string live_event_text(const char* event, const nlohmann::json& data) {
  const std::string id = data.contains("changes") ? fmt::format("id: {}\n", data["changes"].get<std::uint64_t>()) : "";
  return fmt::format("{}event: {}\ndata: {}\n\n", id, event,
                     data.dump(-1, ' ', false, nlohmann::json::error_handler_t::replace));
}

}  // namespace

MapEventStreams::MapEventStreams(const MapService& map, const std::atomic<bool>& stopping, EventStreamOptions options)
    : map_(map), stopping_(stopping), options_(options) {}

void MapEventStreams::open(httplib::Response& res) {
  if (open_.fetch_add(1) >= options_.max_streams) {
    open_.fetch_sub(1);
    res.set_header("Retry-After", "5");
    throw RequestError(503, "", fmt::format("{} event streams are open, the most this server keeps; try again later",
                                            options_.max_streams));
  }
  struct Stream {
    std::optional<std::uint64_t> sent;  // the counter last sent
    nlohmann::json progress;            // the progress last sent (live mode)
    std::chrono::steady_clock::time_point last_write = std::chrono::steady_clock::now();
  };
  auto stream = std::make_shared<Stream>();
  res.set_header("Cache-Control", "no-cache");
  // httplib calls the provider again while it returns true: each call writes what is due or
  // waits one poll interval. A failed write (the client left) or a stopping server ends it.
  res.set_chunked_content_provider(
      "text/event-stream",
      [this, stream](std::size_t, httplib::DataSink& sink) {
        if (stopping_) {
          sink.done();
          return true;
        }
        std::uint64_t changes = map_.changes();
        const auto now = std::chrono::steady_clock::now();
        std::string text;
        const bool first = !stream->sent;
        if (first) text = "retry: 2000\n";
        if (!stream->sent || *stream->sent != changes) {
          // Live mode: what changed since the last event this stream sent (none on the first: the
          // page loads the whole map then), then the counter.
          if (stream->sent)
            for (const nlohmann::json& e : map_.changes_since(*stream->sent)) {
              text += live_event_text("submaps", e);
              changes = std::max(changes, e.at("changes").get<std::uint64_t>());  // one that came meanwhile
            }
          text += map_event_text(map_, changes);
          stream->sent = changes;
        }
        if (nlohmann::json progress = map_.progress(); progress != stream->progress) {
          if (!progress.is_null()) text += live_event_text("progress", progress);
          stream->progress = std::move(progress);
        }
        if (text.empty() && std::chrono::duration<double>(now - stream->last_write).count() >= options_.heartbeat_seconds)
          text = ": heartbeat\n\n";
        if (text.empty()) {
          std::this_thread::sleep_for(std::chrono::duration<double>(options_.poll_seconds));
          return true;
        }
        stream->last_write = now;
        if (!sink.write(text.data(), text.size())) return false;
        if (first) map_.event_stream_opened();  // from now on the client hears of every change
        return true;
      },
      [this](bool) { open_.fetch_sub(1); });
}

}  // namespace slamvdb
