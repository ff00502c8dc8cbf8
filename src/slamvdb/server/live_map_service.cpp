#include "slamvdb/server/live_map_service.hpp"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <set>

#include "slamvdb/io/map_info_json.hpp"
#include "slamvdb/server/request_decoding.hpp"

namespace slamvdb {

namespace live_map_service_detail {

// /api/info of a map in memory: what `info --json` says of a file, from the map itself. The file's
// figures (bytes, voxel counts per submap) are not known while it is written: null.
nlohmann::json live_info_json(const std::string& source, const SemanticMap& map,
                              const std::vector<SubmapInfo>& submaps, std::optional<int> active) {
  MapFileSummary summary;
  summary.params = map.params();
  summary.info = map.info();
  for (const SubmapInfo& s : submaps) summary.submaps.push_back({s, 0, 0, 0, 0});
  summary.known_voxels = map.num_known_voxels();
  summary.occupied_voxels = map.num_occupied_voxels();
  summary.semantic_voxels = map.num_semantic_voxels();
  nlohmann::json j = map_info_json(source, summary, std::nullopt);
  j["format_version"] = nullptr;
  j["bytes"] = nullptr;
  for (nlohmann::json& s : j["submaps"]) {
    for (const char* field : {"blocks", "known_voxels", "occupied_voxels", "semantic_voxels"}) s[field] = nullptr;
    s["active"] = active && s["id"].get<int>() == *active;
  }
  j["submaps_in_memory"] = submaps.size();
  return j;
}

// The /api/info entry of a submap out of memory (its figures unknown, as those of one in memory).
nlohmann::json out_of_memory_entry(const SubmapInfo& s) {
  MapFileSummary summary;
  summary.submaps.push_back({s, 0, 0, 0, 0});
  nlohmann::json j = map_info_json("", summary, std::nullopt).at("submaps").at(0);
  for (const char* field : {"blocks", "known_voxels", "occupied_voxels", "semantic_voxels"}) j[field] = nullptr;
  j["active"] = false;
  return j;
}

nlohmann::json submap_by_id(const nlohmann::json& info, int id) {
  for (const nlohmann::json& s : info.at("submaps"))
    if (s.at("id").get<int>() == id) return s;
  return nullptr;
}

}  // namespace live_map_service_detail

LiveMapService::LiveMapService(std::string source, int dim, LiveMapOptions options)
    : source_(std::move(source)), options_(options), space_{dim, ""} {
  info_ = {{"path", source_}, {"submaps", nlohmann::json::array()}, {"submaps_in_memory", 0}};
  refresher_ = std::thread([this] { refresh_loop(); });
}

LiveMapService::~LiveMapService() {
  {
    const std::lock_guard lock(state_mutex_);
    stopping_ = true;
  }
  wake_.notify_all();
  refresher_.join();
}

void LiveMapService::attach(const SemanticMap& map, std::function<std::vector<SubmapInfo>()> all_submaps) {
  const std::unique_lock lock(source_mutex_);
  map_ = &map;
  all_submaps_ = std::move(all_submaps);
  space_ = {map.params().semantic.dim, map.info().model_id};
  grid_resolution_ = map.params().index_cell();
  // Not owned: the mapper's map lives until detach(), which waits for every reader.
  reader_ = std::make_unique<SemanticMapService>(std::shared_ptr<const SemanticMap>(&map, [](const SemanticMap*) {}),
                                                 nlohmann::json());
  {
    const std::lock_guard state(state_mutex_);
    mapping_ = true;
  }
  refresh_locked();
}

void LiveMapService::detach() {
  const std::unique_lock lock(source_mutex_);
  if (map_) refresh_locked();
  kept_at_detach_.clear();
  if (all_submaps_)
    for (const SubmapInfo& s : all_submaps_()) kept_at_detach_.push_back(s.id);
  reader_.reset();
  map_ = nullptr;
  all_submaps_ = nullptr;
  ended_ = true;
  const std::lock_guard state(state_mutex_);
  mapping_ = false;
}

void LiveMapService::attach_final(std::shared_ptr<const SemanticMap> map) {
  const std::unique_lock lock(source_mutex_);
  final_ = std::move(map);
  map_ = final_.get();
  space_ = {map_->params().semantic.dim, map_->info().model_id};
  grid_resolution_ = map_->params().index_cell();
  reader_ = std::make_unique<SemanticMapService>(final_, nlohmann::json());
  refresh_locked();
}

void LiveMapService::set_progress(std::size_t scans_done, std::size_t scans_total) {
  const std::lock_guard lock(state_mutex_);
  scans_done_ = scans_done;
  scans_total_ = scans_total;
}

void LiveMapService::refresh_loop() {
  std::unique_lock state(state_mutex_);
  while (!stopping_) {
    wake_.wait_for(state, std::chrono::duration<double>(options_.refresh_seconds), [this] { return stopping_; });
    if (stopping_) break;
    state.unlock();
    {
      const std::shared_lock lock(source_mutex_);
      try {
        if (map_) refresh_locked();
      } catch (const std::exception& e) {  // a bug of ours: said, and the next look tries again
        spdlog::error("live map: {}", e.what());
      }
    }
    state.lock();
  }
}

// One look at the map: what appeared, moved, grew, was merged or left memory since the last one
// becomes one event. Only the refresher and attach/detach (exclusive) call it, so two never run at
// once.
void LiveMapService::refresh_locked() {
  using namespace live_map_service_detail;
  const std::vector<SubmapInfo> submaps = map_->submaps();
  const std::optional<int> active = map_->active_submap_id();
  nlohmann::json info = live_info_json(source_, *map_, submaps, active);
  const std::size_t cells = map_->num_index_cells();
  // After the map's own list: a submap that leaves memory between the two reads is in this one.
  const std::vector<SubmapInfo> all = all_submaps_ ? all_submaps_() : std::vector<SubmapInfo>();
  const std::lock_guard state(state_mutex_);
  nlohmann::json added = nlohmann::json::array(), moved = nlohmann::json::array(), grew = nlohmann::json::array(),
                 merged = nlohmann::json::array(), unloaded = nlohmann::json::array();
  std::map<int, SubmapInfo> now;
  for (const SubmapInfo& s : submaps) {
    now[s.id] = s;
    const auto before = seen_.find(s.id);
    if (before == seen_.end()) {
      added.push_back(submap_by_id(info, s.id));
    } else if (before->second.T_world_submap.matrix() != s.T_world_submap.matrix()) {
      moved.push_back(submap_by_id(info, s.id));
    } else if (before->second.time_range.end != s.time_range.end || before->second.finished != s.finished) {
      grew.push_back(s.id);  // scans or images went into it, or it was finished
    }
  }
  // Where a merge put a submap's voxels: the first submap in memory at this look along its merges
  // (A into B, then B into C between two looks: C), else the last one (itself out of memory).
  const auto merged_home = [&](int id) {
    std::optional<int> into = map_->merged_into(id);
    while (into && !now.count(*into))
      if (const std::optional<int> next = map_->merged_into(*into)) into = next;
      else break;
    return into;
  };
  // A submap out of memory comes back for a merge (Mapper::merge_submaps reads both back), maybe
  // between two looks: then it was never seen back, and only the merge record says it is gone.
  for (auto it = out_of_memory_.begin(); it != out_of_memory_.end();) {
    if (now.count(it->first)) {
      it = out_of_memory_.erase(it);  // read back: `added` above
    } else if (const std::optional<int> into = merged_home(it->first)) {
      merged.push_back({{"id", it->first}, {"into", *into}});
      it = out_of_memory_.erase(it);
    } else {
      ++it;
    }
  }
  // Every submap that leaves the map is merged (recorded by the map) or removed by its holder,
  // who keeps it (the mapper's store: --unload-radius / --max-memory): nothing else vanishes.
  for (const auto& [id, s] : seen_) {
    if (now.count(id)) continue;
    if (const std::optional<int> into = merged_home(id)) {
      merged.push_back({{"id", id}, {"into", *into}});
    } else {
      unloaded.push_back(id);
      out_of_memory_.emplace(id, s);
    }
  }
  // A correction moves submaps out of memory where their holder keeps them (Mapper::correct_submaps
  // reads nothing back): their new anchors, told as `moved` like those of submaps in memory.
  for (const SubmapInfo& s : all) {
    const auto kept = out_of_memory_.find(s.id);
    if (kept == out_of_memory_.end() || kept->second.T_world_submap.matrix() == s.T_world_submap.matrix()) continue;
    kept->second = s;
    moved.push_back(out_of_memory_entry(s));
  }
  info_ = std::move(info);
  semantic_cells_ = cells;
  seen_ = std::move(now);
  const bool active_changed = active != active_;
  active_ = active;
  if (added.empty() && moved.empty() && grew.empty() && merged.empty() && unloaded.empty() && !active_changed) return;
  ++changes_;
  events_.push_back({{"changes", changes_},
                     {"added", std::move(added)},
                     {"moved", std::move(moved)},
                     {"grew", std::move(grew)},
                     {"merged", std::move(merged)},
                     {"unloaded", std::move(unloaded)},
                     {"active", active ? nlohmann::json(*active) : nlohmann::json()}});
  while (events_.size() > options_.max_events) events_.pop_front();
}

std::uint64_t LiveMapService::changes() const {
  const std::lock_guard lock(state_mutex_);
  return changes_;
}

nlohmann::json LiveMapService::changes_since(std::uint64_t after) const {
  const std::lock_guard lock(state_mutex_);
  nlohmann::json out = nlohmann::json::array();
  if (after >= changes_) return out;
  if (events_.empty() || events_.front().at("changes").get<std::uint64_t>() > after + 1) {
    // The stream fell behind the events kept: it reloads everything instead, but for the submaps
    // out of memory (listed, with their anchors): the reload cannot bring them (reads are from
    // memory), so what the page drew of them is kept and placed where they are now.
    nlohmann::json unloaded = nlohmann::json::array(), moved = nlohmann::json::array();
    for (const auto& [id, s] : out_of_memory_) {
      unloaded.push_back(id);
      moved.push_back(live_map_service_detail::out_of_memory_entry(s));
    }
    out.push_back({{"changes", changes_},
                   {"resync", true},
                   {"unloaded", std::move(unloaded)},
                   {"moved", std::move(moved)},
                   {"active", active_ ? nlohmann::json(*active_) : nlohmann::json()}});
    return out;
  }
  for (const nlohmann::json& e : events_)
    if (e.at("changes").get<std::uint64_t>() > after) out.push_back(e);
  return out;
}

nlohmann::json LiveMapService::progress() const {
  const std::lock_guard lock(state_mutex_);
  return {{"mapping", mapping_}, {"scans_done", scans_done_}, {"scans_total", scans_total_}};
}

void LiveMapService::event_stream_opened() const {
  {
    const std::lock_guard lock(state_mutex_);
    ++streams_opened_;
  }
  stream_opened_.notify_all();
}

bool LiveMapService::wait_for_viewer(double timeout_seconds) const {
  std::unique_lock lock(state_mutex_);
  return stream_opened_.wait_for(lock, std::chrono::duration<double>(timeout_seconds),
                                 [this] { return streams_opened_ > 0; });
}

std::vector<int> LiveMapService::submaps_out_of_memory() const {
  const std::shared_lock lock(source_mutex_);
  if (!map_) return {};
  // The holder's list first: a submap that leaves memory between the two reads is in it, and
  // not in the map's (told as left out); one read back meanwhile is in both (not told).
  std::set<int> out;
  if (all_submaps_) {
    for (const SubmapInfo& s : all_submaps_()) out.insert(s.id);
  } else {
    out.insert(kept_at_detach_.begin(), kept_at_detach_.end());
  }
  for (const SubmapInfo& s : map_->submaps()) out.erase(s.id);
  std::erase_if(out, [this](int id) { return map_->merged_into(id).has_value(); });
  return {out.begin(), out.end()};
}

nlohmann::json LiveMapService::info() const {
  const std::lock_guard lock(state_mutex_);
  nlohmann::json j = info_;
  j["live"] = {{"mapping", mapping_}, {"scans_done", scans_done_}, {"scans_total", scans_total_}, {"changes", changes_}};
  return j;
}

std::size_t LiveMapService::semantic_cells() const {
  const std::lock_guard lock(state_mutex_);
  return semantic_cells_;
}

template <class F>
auto LiveMapService::read(F&& f) const {
  const std::shared_lock lock(source_mutex_);
  if (!reader_)
    throw RequestError(503, "", ended_ ? "mapping is ending: the map is being saved; try again in a moment"
                                       : "mapping has not started yet; try again in a moment");
  return f(*reader_);
}

QuerySpace LiveMapService::space() const {
  const std::shared_lock lock(source_mutex_);
  return space_;
}

double LiveMapService::grid_resolution() const {
  const std::shared_lock lock(source_mutex_);
  return grid_resolution_;
}

MapService::SearchAnswer LiveMapService::search(std::span<const float> query, const SearchOptions& options,
                                                bool exact) const {
  return read([&](const SemanticMapService& m) { return m.search(query, options, exact); });
}

std::vector<PointQuery> LiveMapService::at(std::span<const Vec3d> points_world, const QuerySet* queries,
                                           const ClassifyOptions& options, ModelIdCheck model_check,
                                           bool with_embeddings) const {
  return read([&](const SemanticMapService& m) {
    return m.at(points_world, queries, options, model_check, with_embeddings);
  });
}

void LiveMapService::classify(const QuerySet& queries, std::span<ScoredCell> results, const ClassifyOptions& options,
                              ModelIdCheck model_check) const {
  read([&](const SemanticMapService& m) {
    m.classify(queries, results, options, model_check);
    return 0;
  });
}

std::vector<ClassifiedCell> LiveMapService::classes(const QuerySet& queries, const QueryRegion& region,
                                                    const ClassifyOptions& options, ModelIdCheck model_check) const {
  return read([&](const SemanticMapService& m) { return m.classes(queries, region, options, model_check); });
}

std::size_t LiveMapService::region_cells(const QueryRegion& region) const {
  return read([&](const SemanticMapService& m) { return m.region_cells(region); });
}

MapService::RegionGrid LiveMapService::nav_grid(const QuerySet& queries, const NavGridOptions& options,
                                                const ClassifyOptions& classify, ModelIdCheck model_check) const {
  return read([&](const SemanticMapService& m) { return m.nav_grid(queries, options, classify, model_check); });
}

PointChunks LiveMapService::points(const PointsRequest& request, const PointValueSource& values) const {
  return read([&](const SemanticMapService& m) { return m.points(request, values); });
}

}  // namespace slamvdb
