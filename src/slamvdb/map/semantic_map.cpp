#include "slamvdb/map/semantic_map.hpp"

#include <fmt/format.h>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

// Submaps of one map must agree on everything that defines a voxel and an embedding.
bool same_voxel_params(const MapParams& a, const MapParams& b) {
  const OccupancyParams &x = a.occupancy, &y = b.occupancy;
  return x.voxel_size == y.voxel_size && x.log_odds_hit == y.log_odds_hit && x.log_odds_miss == y.log_odds_miss &&
         x.clamp_min == y.clamp_min && x.clamp_max == y.clamp_max && x.occupied_threshold == y.occupied_threshold &&
         a.semantic.dim == b.semantic.dim;
}

void check_rigid(int id, const Pose& T) {
  const Eigen::Matrix4d& m = T.matrix();
  const Eigen::Matrix3d R = T.linear();
  const bool rigid = m.allFinite() && (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < 1e-6 &&
                     std::abs(R.determinant() - 1.0) < 1e-6 && m.row(3).isApprox(Eigen::RowVector4d(0, 0, 0, 1));
  if (!rigid) throw Error(fmt::format("pose of submap {} is not a finite rigid transform", id));
  if (!in_grid_extent(T.translation() / 1e-3))  // far inside what any grid can hold at 1 mm
    throw Error(fmt::format("pose of submap {} lies outside the representable extent", id));
}

// Working precision of the active submap: fp32, so that the running mean keeps learning.
constexpr EmbeddingPrecision kActivePrecision = EmbeddingPrecision::kFloat32;

}  // namespace

void check_submap_pose(int id, const Pose& T_world_submap) { check_rigid(id, T_world_submap); }

struct SemanticMap::ReadGuard {
  ReadLock map;
  std::optional<ReadLock> active;
  explicit ReadGuard(const SemanticMap& m) : map(m.mutex_) {
    if (const Submap* a = m.active()) active.emplace(a->data_mutex_);
  }
};

SemanticMap::SemanticMap(const MapParams& params, MapInfo info)
    : params_(params), info_(std::move(info)), index_(params.index_cell(), params.semantic.dim, params.semantic.single_view) {
  params_.validate();
}

SemanticMap::SemanticMap(SemanticMap&& other) noexcept
    : params_(other.params_), info_(std::move(other.info_)), slots_(std::move(other.slots_)),
      ids_(std::move(other.ids_)), merged_into_(std::move(other.merged_into_)), active_slot_(other.active_slot_), index_(std::move(other.index_)),
      next_id_(other.next_id_), last_scan_position_(other.last_scan_position_) {}

uint32_t SemanticMap::slot_of(int id) const {
  const auto it = ids_.find(id);
  if (it == ids_.end()) throw Error(fmt::format("there is no submap {}", id));
  return it->second;
}

// A new submap's frame: axes parallel to the world's, origin at the voxel corner nearest to the
// sensor. Any frame would do for a free-floating submap; this one puts every uncorrected submap on
// one common grid, so index reads, world occupancy and merges need no resampling until a loop
// closure actually rotates a submap (and then only by the correction).
Pose SemanticMap::anchor_for(const Pose& T_world_sensor) const {
  const double vs = params_.occupancy.voxel_size;
  Pose T = Pose::Identity();
  T.translation() = (T_world_sensor.translation() / vs).array().round().matrix() * vs;
  return T;
}

int SemanticMap::start_submap_locked(const Pose& T_world_submap) {
  check_rigid(next_id_, T_world_submap);
  if (active_slot_) finish_active_locked();
  SubmapInfo info;
  info.id = next_id_++;
  info.T_world_submap = T_world_submap;
  auto submap = std::make_unique<Submap>(info, VoxelMap(params_, kActivePrecision));
  submap->voxels_.semantics().set_change_tracking(true);
  const auto slot = static_cast<uint32_t>(slots_.size());
  index_.add_submap(slot, submap->voxels_.semantics(), params_.occupancy.voxel_size, T_world_submap);
  slots_.push_back(std::move(submap));
  ids_[info.id] = slot;
  active_slot_ = slot;
  return info.id;
}

void SemanticMap::finish_active_locked() {
  Submap* a = active();
  if (!a) return;
  sync_active_locked();
  SemanticLayer& layer = a->voxels_.semantics();
  layer.set_change_tracking(false);
  layer.convert_to(params_.semantic.precision);  // handles stay valid: the index needs no work
  a->info_.finished = true;
  active_slot_.reset();
}

void SemanticMap::sync_active_locked() {
  if (Submap* a = active()) index_.apply_changes(*active_slot_, a->voxels_.semantics().take_changes());
}

int SemanticMap::start_submap(const Pose& T_world_submap) {
  WriteLock lock(mutex_);
  last_scan_position_.reset();
  return start_submap_locked(T_world_submap);
}

void SemanticMap::finish_active_submap() {
  WriteLock lock(mutex_);
  finish_active_locked();
  last_scan_position_.reset();
}

std::optional<int> SemanticMap::active_submap_id() const {
  ReadLock lock(mutex_);
  if (const Submap* a = active()) return a->id();
  return std::nullopt;
}

ScanIntegrationStats SemanticMap::integrate_scan(double stamp, const std::vector<Vec3f>& points_sensor,
                                                 const Pose& T_world_sensor) {
  Submap* a = nullptr;
  Pose T_world_submap;
  {
    WriteLock lock(mutex_);
    const Vec3d position = T_world_sensor.translation();
    if (active() && last_scan_position_) active()->info_.path_length += (position - *last_scan_position_).norm();
    if (!active() || (params_.submap_length > 0 && active()->info_.path_length >= params_.submap_length))
      start_submap_locked(anchor_for(T_world_sensor));
    last_scan_position_ = position;
    a = active();
    a->info_.time_range.extend(stamp);
    T_world_submap = a->T_world_submap();
  }
  ScanIntegrationStats stats;
  {
    WriteLock data(a->data_mutex_);
    stats = a->voxels_.integrate_scan(points_sensor, T_world_submap.inverse() * T_world_sensor);
  }
  WriteLock lock(mutex_);
  sync_active_locked();
  return stats;
}

bool SemanticMap::update_active(double stamp, const ActiveUpdate& f) {
  Submap* a = nullptr;
  {
    ReadLock lock(mutex_);  // finished submaps stay as they are while f reads them
    a = active();
    if (!a) return false;
    std::vector<PlacedVoxelMap> finished;
    for (const auto& [id, slot] : ids_)
      if (slots_[slot]->finished()) finished.push_back({&slots_[slot]->voxels_, slots_[slot]->T_world_submap()});
    WriteLock data(a->data_mutex_);
    f(a->voxels_, a->T_world_submap(), finished);
  }
  WriteLock lock(mutex_);
  a->info_.time_range.extend(stamp);
  sync_active_locked();
  return true;
}

void SemanticMap::set_submap_poses(const std::map<int, Pose>& T_world_submap) {
  WriteLock lock(mutex_);
  for (const auto& [id, T] : T_world_submap) {
    slot_of(id);
    check_rigid(id, T);
  }
  for (const auto& [id, T] : T_world_submap) {
    const uint32_t slot = slot_of(id);
    slots_[slot]->info_.T_world_submap = T;
    index_.move_submap(slot, T);
  }
}

MergeReport SemanticMap::merge_submaps(int target_id, int source_id, const MergeOptions& options) {
  WriteLock lock(mutex_);
  const uint32_t ts = slot_of(target_id), ss = slot_of(source_id);
  if (ts == ss) throw Error(fmt::format("cannot merge submap {} with itself", target_id));
  Submap &target = *slots_[ts], &source = *slots_[ss];
  if (!target.finished() || !source.finished())
    throw Error(fmt::format("cannot merge submaps {} and {}: the active submap {} is still being written; finish it first",
                            target_id, source_id, target.finished() ? source_id : target_id));
  const Pose T_target_source = target.T_world_submap().inverse() * source.T_world_submap();
  MergeReport report;
  report.overlap = occupied_overlap(target.voxels_, source.voxels_, T_target_source);
  if (report.overlap < options.min_overlap) {
    report.refused = fmt::format("the submaps overlap by {:.1f}% of their occupied voxels, less than the {:.1f}% required",
                                 100 * report.overlap, 100 * options.min_overlap);
    return report;
  }
  index_.remove_submap(ss);
  index_.remove_submap(ts);
  const double overlap = report.overlap;
  report = merge_into(target.voxels_, source.voxels_, T_target_source);
  report.overlap = overlap;
  target.info_.time_range.extend(source.info_.time_range);
  target.info_.path_length += source.info_.path_length;
  slots_[ss].reset();
  ids_.erase(source_id);
  merged_into_[source_id] = target_id;
  index_.add_submap(ts, target.voxels_.semantics(), params_.occupancy.voxel_size, target.T_world_submap());
  return report;
}

void SemanticMap::add_finished_submap(SubmapInfo info, VoxelMap voxels) {
  if (!same_voxel_params(voxels.params(), params_))
    throw Error(fmt::format("submap {} has voxel or embedding parameters different from the map's", info.id));
  check_rigid(info.id, info.T_world_submap);
  voxels.semantics().set_change_tracking(false);
  voxels.semantics().convert_to(params_.semantic.precision);
  voxels.semantics().set_own_session(info.session);  // what its entries' kOwnSession means
  info.finished = true;
  WriteLock lock(mutex_);
  if (ids_.contains(info.id)) throw Error(fmt::format("submap id {} appears twice", info.id));
  const auto slot = static_cast<uint32_t>(slots_.size());
  slots_.push_back(std::make_unique<Submap>(info, std::move(voxels)));
  index_.add_submap(slot, slots_.back()->voxels_.semantics(), params_.occupancy.voxel_size, info.T_world_submap);
  ids_[info.id] = slot;
  next_id_ = std::max(next_id_, info.id + 1);
}

std::pair<SubmapInfo, VoxelMap> SemanticMap::remove_finished_submap(int id) {
  WriteLock lock(mutex_);
  const uint32_t slot = slot_of(id);
  if (!slots_[slot]->finished()) throw Error(fmt::format("submap {} is still being written; it cannot leave memory", id));
  index_.remove_submap(slot);
  std::pair<SubmapInfo, VoxelMap> out{slots_[slot]->info_, std::move(slots_[slot]->voxels_)};
  slots_[slot].reset();
  ids_.erase(id);
  return out;
}

std::vector<std::pair<SubmapInfo, VoxelMap>> SemanticMap::take_finished_submaps() {
  WriteLock lock(mutex_);
  std::vector<std::pair<SubmapInfo, VoxelMap>> out;
  if (!active_slot_) index_ = GlobalIndex(params_.index_cell(), params_.semantic.dim, params_.semantic.single_view);
  for (auto it = ids_.begin(); it != ids_.end();) {
    const uint32_t slot = it->second;
    if (!slots_[slot]->finished()) {
      ++it;
      continue;
    }
    if (active_slot_) index_.remove_submap(slot);
    out.emplace_back(slots_[slot]->info_, std::move(slots_[slot]->voxels_));
    slots_[slot].reset();
    it = ids_.erase(it);
  }
  return out;
}

std::vector<SubmapInfo> SemanticMap::submaps() const {
  ReadLock lock(mutex_);
  std::vector<SubmapInfo> out;
  for (const auto& [id, slot] : ids_) out.push_back(slots_[slot]->info());
  return out;
}

std::optional<SubmapInfo> SemanticMap::submap_info(int id) const {
  ReadLock lock(mutex_);
  const auto it = ids_.find(id);
  if (it == ids_.end()) return std::nullopt;
  return slots_[it->second]->info();
}

std::optional<int> SemanticMap::merged_into(int id) const {
  ReadLock lock(mutex_);
  const auto it = merged_into_.find(id);
  if (it == merged_into_.end()) return std::nullopt;
  return it->second;
}

void SemanticMap::read_submap(int id, const std::function<void(const Submap&)>& f) const {
  ReadLock lock(mutex_);
  const Submap& s = *slots_[slot_of(id)];
  if (s.finished()) return f(s);
  ReadLock data(s.data_mutex_);
  f(s);
}

void SemanticMap::read_index(const std::function<void(const GlobalIndex&)>& f) const {
  const ReadGuard guard(*this);
  f(index_);
}

std::vector<WorldOccupancyCell> SemanticMap::world_occupancy() const {
  const ReadGuard guard(*this);
  std::vector<PlacedVoxelMap> placed;
  for (const auto& [id, slot] : ids_) placed.push_back({&slots_[slot]->voxels_, slots_[slot]->T_world_submap()});
  return combine_occupancy(placed, index_.cell_size(), params_.occupancy);
}

std::size_t SemanticMap::num_submaps() const {
  ReadLock lock(mutex_);
  return ids_.size();
}

namespace {
template <class F>
std::size_t sum_over(const std::map<int, uint32_t>& ids, const std::vector<std::unique_ptr<Submap>>& slots, F&& f) {
  std::size_t n = 0;
  for (const auto& [id, slot] : ids) n += f(slots[slot]->voxels());
  return n;
}
}  // namespace

std::size_t SemanticMap::num_known_voxels() const {
  const ReadGuard guard(*this);
  return sum_over(ids_, slots_, [](const VoxelMap& v) { return v.occupancy().num_known_voxels(); });
}
std::size_t SemanticMap::num_occupied_voxels() const {
  const ReadGuard guard(*this);
  return sum_over(ids_, slots_, [](const VoxelMap& v) { return v.occupancy().num_occupied_voxels(); });
}
std::size_t SemanticMap::num_semantic_voxels() const {
  const ReadGuard guard(*this);
  return sum_over(ids_, slots_, [](const VoxelMap& v) { return v.semantics().size(); });
}
std::size_t SemanticMap::num_index_cells() const {
  ReadLock lock(mutex_);
  return index_.size();
}
std::size_t SemanticMap::memory_bytes() const {
  const ReadGuard guard(*this);
  return index_.memory_bytes() + sum_over(ids_, slots_, [](const VoxelMap& v) {
           return v.occupancy().memory_bytes() + v.semantics().memory_bytes();
         });
}

}  // namespace slamvdb
