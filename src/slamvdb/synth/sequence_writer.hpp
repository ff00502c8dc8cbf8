#pragma once
// Writes a simulated sequence to disk in the RELLIS-3D layout:
//   os1_cloud_node_kitti_bin/000000.bin                  N x (x y z intensity) float32, LiDAR frame
//   os1_cloud_node_semantickitti_label_id/000000.label   N x uint32, low 16 bits = class id
//   pylon_camera_node/frame000000-SEC_MSEC.jpg           RGB image, the name carries its stamp
//   pylon_camera_node_label_id/frame000000-SEC_MSEC.png  uint8 class ids, same stem
//   pylon_camera_node_sim_view/frame000000-SEC_MSEC.png  SIMULATED view geometry at half the image size
//                                                        (16-bit, core/simulated_view.hpp; not in RELLIS-3D;
//                                                        unless config.view_geometry is off; the folder
//                                                        name is io's kRellisSimViewDir)
//   os1_cloud_node_point_times/000000.bin               with config.lidar_sweep_s > 0 only: SIMULATED per-point
//                                                        times, N x uint32 ns since the scan's stamp (the form
//                                                        tests/recording_fixtures' --point-times reads; not in
//                                                        RELLIS-3D, and the folder readers do not read it)
//   poses.txt        per scan: KITTI 3x4 row-major T_world_lidar (at the stamp: the start of a swept scan)
//   times.txt        per scan: stamp in seconds (our addition; RELLIS-3D has none)
//   camera_info.txt  "fx fy cx cy" at the written image size, then "k1 k2 p1 p2 k3"
//   transforms.yaml  os1_cloud_node-pylon_camera_node: q (w x y z), t (x y z) = T_lidar_camera
//   synth.json       "simulated": true, seed, every parameter, counts, classes
// The bytes depend only on the configuration (seed included), never on the thread count.
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "slamvdb/synth/world.hpp"

namespace slamvdb::synth {

inline constexpr const char* kLidarDir = "os1_cloud_node_kitti_bin";
inline constexpr const char* kLidarLabelDir = "os1_cloud_node_semantickitti_label_id";
inline constexpr const char* kImageDir = "pylon_camera_node";
inline constexpr const char* kImageLabelDir = "pylon_camera_node_label_id";
inline constexpr const char* kPointTimesDir = "os1_cloud_node_point_times";

// "frame000012-1700000001_234" for frame 12 at 1700000001.234 s.
std::string camera_frame_stem(std::size_t frame, int64_t stamp_ms);

struct SynthSummary {
  std::size_t scans = 0, images = 0;
  std::size_t points = 0;                           // points written (including all-zero no-return points if kept)
  std::size_t no_returns = 0;                       // rays without a return (dropped unless keep_no_return)
  std::array<std::size_t, 256> points_per_class{};  // labelled LiDAR returns per class id
  double path_length_m = 0.0;
  double loop_perimeter_m = 0.0;
  std::uintmax_t bytes = 0;  // everything written, synth.json included
};

using SynthProgress = std::function<void(std::size_t done, std::size_t total)>;

// Builds the world and writes every scan and image (in parallel). `out` must be missing or empty,
// unless `overwrite`, which first removes the files and folders of an earlier sequence there.
// Throws Error on bad settings or any write failure (naming the file). The sequence is marked
// incomplete (kIncompleteMarker, io/sequence_reader.hpp) from the start until every file is
// written and synced, and each file is written under a temporary name and renamed: a run that
// fails (full disk, ...) or is killed leaves a sequence that read_sequence refuses, never one
// that looks complete.
SynthSummary write_synthetic_sequence(const SynthConfig& config, const std::filesystem::path& out,
                                      bool overwrite = false, const SynthProgress& progress = {});

}  // namespace slamvdb::synth
