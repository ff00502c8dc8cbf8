#pragma once
// Live mode of the server (`slamvdb map|slam --serve`, issue 21): the map a running mapper builds,
// served while it grows. Every read goes to a SemanticMapService over the mapper's map (its locks
// make reading safe while the mapping thread writes); a refresh thread looks at the map at a
// bounded rate and turns what changed into events for GET /api/events: submaps that appeared,
// moved (loop corrections), grew (the active submap), were merged into another (loop closures:
// SemanticMap::merged_into says which) or were unloaded (left memory far from the vehicle, kept in
// the map file), with the change counter, plus the scans done. The map is read from memory only:
// unloaded submaps are not answered, and every answer of a question says which were left out
// (submaps_out_of_memory: "submaps_not_searched" in /api/query, /api/at, /api/classes); a
// correction that moves one is still told (`moved`, from its holder's anchors: Mapper::submaps),
// so that the page re-places what it drew of it.
//
// Life: attach() when mapping starts (PipelineOptions::map_started), detach() before the mapper
// hands the map out (map_ending: waits for reads in flight; from then on reads answer 503 until
// attach_final, if ever, gives the saved map).
#include <condition_variable>
#include <deque>
#include <functional>
#include <map>
#include <optional>
#include <set>
#include <shared_mutex>
#include <thread>
#include <vector>

#include "slamvdb/core/fair_shared_mutex.hpp"

#include "slamvdb/server/map_service.hpp"

namespace slamvdb {

struct LiveMapOptions {
  double refresh_seconds = 0.5;  // how often the map is looked at (the active submap's refresh rate)
  std::size_t max_events = 256;  // events kept for streams that fall behind (older: a "resync")
};

class LiveMapService final : public MapService {
 public:
  // `source`: what the map is built from (shown as /api/info "path"); `dim`: its embeddings'.
  LiveMapService(std::string source, int dim, LiveMapOptions options = {});
  ~LiveMapService() override;
  LiveMapService(const LiveMapService&) = delete;
  LiveMapService& operator=(const LiveMapService&) = delete;

  // The mapper's map, until detach(); `all_submaps` (may be empty): every submap's info, in memory
  // or kept by the map's holder (Mapper::submaps), for the anchors of those out of memory.
  void attach(const SemanticMap& map, std::function<std::vector<SubmapInfo>()> all_submaps = {});
  void detach();                        // a last look at the map first (the last submap finished)
  // The saved map, served from then on (`--serve-linger`); mapping is over.
  void attach_final(std::shared_ptr<const SemanticMap> map);
  void set_progress(std::size_t scans_done, std::size_t scans_total);

  std::string source_kind() const override { return "live"; }
  std::uint64_t changes() const override;
  nlohmann::json changes_since(std::uint64_t after) const override;
  nlohmann::json progress() const override;
  void event_stream_opened() const override;
  // Submaps out of memory now: every submap the holder keeps (Mapper::submaps; after detach(), those
  // it kept then) but the map in memory has not, merged ones left out (their voxels went into a
  // submap that is listed if it is out of memory itself).
  std::vector<int> submaps_out_of_memory() const override;
  // Blocks until a GET /api/events stream has opened since construction, or `timeout_seconds` have
  // passed: whether one did (`map --serve-wait-viewer`).
  bool wait_for_viewer(double timeout_seconds) const;

  QuerySpace space() const override;
  std::size_t semantic_cells() const override;
  nlohmann::json info() const override;
  SearchAnswer search(std::span<const float> query, const SearchOptions& options, bool exact) const override;
  std::vector<PointQuery> at(std::span<const Vec3d> points_world, const QuerySet* queries,
                             const ClassifyOptions& options, ModelIdCheck model_check,
                             bool with_embeddings) const override;
  void classify(const QuerySet& queries, std::span<ScoredCell> results, const ClassifyOptions& options,
                ModelIdCheck model_check) const override;
  std::vector<ClassifiedCell> classes(const QuerySet& queries, const QueryRegion& region,
                                      const ClassifyOptions& options, ModelIdCheck model_check) const override;
  std::size_t region_cells(const QueryRegion& region) const override;
  RegionGrid nav_grid(const QuerySet& queries, const NavGridOptions& options, const ClassifyOptions& classify,
                      ModelIdCheck model_check) const override;
  double grid_resolution() const override;
  PointChunks points(const PointsRequest& request, const PointValueSource& values) const override;

 private:
  // Runs f(the service over the current map) under the shared lock; 503 while there is none.
  template <class F>
  auto read(F&& f) const;
  void refresh_locked();  // source_mutex_ held (shared or exclusive)
  void refresh_loop();

  const std::string source_;
  const LiveMapOptions options_;
  QuerySpace space_;
  double grid_resolution_ = 0;

  // map_ and reader_; fair: a detach() waits for the reads in flight, not for every later one
  mutable FairSharedMutex source_mutex_;
  const SemanticMap* map_ = nullptr;
  std::function<std::vector<SubmapInfo>()> all_submaps_;
  std::shared_ptr<const SemanticMap> final_;
  std::unique_ptr<SemanticMapService> reader_;
  bool ended_ = false;  // detach() was called
  std::vector<int> kept_at_detach_;  // the holder's submaps at detach(), for the saved map's answers

  mutable std::mutex state_mutex_;  // everything below
  std::condition_variable wake_;
  bool stopping_ = false, mapping_ = false;
  std::size_t scans_done_ = 0, scans_total_ = 0;
  std::uint64_t changes_ = 0;
  std::map<int, SubmapInfo> seen_;  // the submaps at the last look, by id
  // Reported unloaded, not seen back or merged since: with the anchor last told.
  std::map<int, SubmapInfo> out_of_memory_;
  std::optional<int> active_;
  nlohmann::json info_;             // /api/info at the last look
  std::size_t semantic_cells_ = 0;
  mutable std::size_t streams_opened_ = 0;
  mutable std::condition_variable stream_opened_;
  std::deque<nlohmann::json> events_;  // the last max_events "submaps" events, oldest first
  std::thread refresher_;
};

}  // namespace slamvdb
