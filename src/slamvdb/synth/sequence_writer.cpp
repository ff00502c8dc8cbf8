#include "slamvdb/synth/sequence_writer.hpp"

#include <fmt/format.h>
#include <tbb/parallel_for.h>

#include <bit>
#include <cmath>
#include <mutex>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>  // the cv::ImwriteFlags
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/ontology.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/rellis_reader.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/synth/camera_sim.hpp"
#include "slamvdb/io/image_codecs.hpp"

namespace slamvdb::synth {

namespace fs = std::filesystem;

namespace {

static_assert(std::endian::native == std::endian::little, "the .bin/.label files are written little-endian as-is");

constexpr std::array<const char*, 5> kTopFiles = {"poses.txt", "times.txt", "camera_info.txt", "transforms.yaml",
                                                  "synth.json"};

// The incomplete-sequence marker goes in first (durably) and comes out last: a synth run that fails
// or is killed anywhere in between leaves a sequence that read_sequence refuses.
void prepare_output(const fs::path& out, bool overwrite, bool point_times) {
  std::error_code ec;
  if (fs::exists(out, ec) && !fs::is_directory(out, ec))
    throw Error(fmt::format("output {} exists and is not a directory", out.string()));
  if (fs::exists(out, ec) && !fs::is_empty(out, ec) && !overwrite) {
    if (fs::exists(out / kIncompleteMarker, ec))
      throw Error(fmt::format("output directory {} holds an incomplete sequence (an earlier synth failed or was "
                              "killed); pass --force to replace it",
                              out.string()));
    throw Error(
        fmt::format("output directory {} is not empty; choose an empty one or pass --force to replace "
                    "the sequence in it",
                    out.string()));
  }
  fs::create_directories(out, ec);
  if (ec) throw Error(fmt::format("cannot create {}: {}", out.string(), ec.message()));
  write_output_file(out / kIncompleteMarker,
                        "slamvdb synth is writing this sequence; if this file remains, it failed or was killed\n");
  for (const char* dir : {kLidarDir, kLidarLabelDir, kImageDir, kImageLabelDir, kRellisSimViewDir.data(), kPointTimesDir}) {
    fs::remove_all(out / dir, ec);
    if (ec) throw Error(fmt::format("cannot remove the earlier {}: {}", (out / dir).string(), ec.message()));
  }
  for (const char* file : kTopFiles) fs::remove(out / file, ec);
  remove_stale_temp_files(out);
  for (const char* dir : {kLidarDir, kLidarLabelDir, kImageDir, kImageLabelDir, kRellisSimViewDir.data()}) {
    fs::create_directories(out / dir, ec);
    if (ec) throw Error(fmt::format("cannot create {}: {}", (out / dir).string(), ec.message()));
  }
  if (point_times) {
    fs::create_directories(out / kPointTimesDir, ec);
    if (ec) throw Error(fmt::format("cannot create {}: {}", (out / kPointTimesDir).string(), ec.message()));
  }
}

// Every file is written under a temporary name and renamed (core/output_file.hpp), unsynced: the
// file system is synced once at the end, before the marker is removed.
constexpr OutputOptions kUnsynced{.sync = false};

void write_bytes(const fs::path& path, const void* data, std::size_t size) {
  write_output_file(path, std::string_view(static_cast<const char*>(data), size), kUnsynced);
}

void write_text(const fs::path& path, const std::string& text) { write_bytes(path, text.data(), text.size()); }

void write_image(const fs::path& path, const cv::Mat& image, const std::vector<int>& params) {
  std::vector<uchar> encoded;
  try {
    if (!encode_image(path.extension().string(), image, encoded, params))
      throw Error(fmt::format("cannot encode {}", path.string()));
  } catch (const cv::Exception& e) {
    throw Error(fmt::format("cannot encode {}: {}", path.string(), e.what()));
  }
  write_bytes(path, encoded.data(), encoded.size());
}

std::string pose_line(const Pose& T) {
  const Eigen::Matrix<double, 3, 4> M = T.matrix().topRows<3>();
  std::string line;
  for (int r = 0; r < 3; ++r)
    for (int c = 0; c < 4; ++c) line += fmt::format("{}{:.9e}", r + c == 0 ? "" : " ", M(r, c));
  return line + "\n";
}

std::string transforms_yaml(const Pose& T_lidar_camera) {
  const Eigen::Quaterniond q(T_lidar_camera.linear());
  const Vec3d t = T_lidar_camera.translation();
  return fmt::format(
      "os1_cloud_node-pylon_camera_node:\n  q:\n    w: {:.8f}\n    x: {:.8f}\n    y: {:.8f}\n    z: {:.8f}\n"
      "  t:\n    x: {:.8f}\n    y: {:.8f}\n    z: {:.8f}\n",
      q.w(), q.x(), q.y(), q.z(), t.x(), t.y(), t.z());
}

nlohmann::json config_json(const SynthConfig& c) {
  return {{"length_m", c.length_m},
          {"speed_mps", c.speed_mps},
          {"revisit_overlap_m", c.revisit_overlap_m},
          {"min_loop_m", c.min_loop_m},
          {"loop_length_m", c.loop_length_m},
          {"start_offset_m", c.start_offset_m},
          {"reverse", c.reverse},
          {"noise_seed", c.sensor_seed()},
          {"sensor_height_m", c.sensor_height_m},
          {"lidar_rate_hz", c.lidar_rate_hz},
          {"camera_rate_hz", c.camera_rate_hz},
          {"camera_offset_s", c.camera_offset_s},
          {"camera_jitter_s", c.camera_jitter_s},
          {"camera_max_range_m", c.camera_max_range_m},
          {"image_width", c.image_width},
          {"image_height", c.image_height},
          {"jpeg_quality", c.jpeg_quality},
          {"keep_no_return", c.keep_no_return},
          {"lidar_sweep_s", c.lidar_sweep_s},
          {"base_stamp", c.base_stamp},
          {"rig_translation_error_m", c.rig_translation_error_m},
          {"rig_rotation_error_deg", c.rig_rotation_error_deg},
          {"rig_time_offset_s", c.rig_time_offset_s},
          {"view_geometry", c.view_geometry},
          {"lidar",
           {{"beams", c.lidar.beams},
            {"columns", c.lidar.columns},
            {"fov_up_deg", c.lidar.fov_up_deg},
            {"fov_down_deg", c.lidar.fov_down_deg},
            {"min_range_m", c.lidar.min_range},
            {"max_range_m", c.lidar.max_range},
            {"range_noise_sigma_m", c.lidar.range_noise_sigma}}}};
}

nlohmann::json class_list(const SynthWorld& world, const SynthSummary& summary) {
  std::vector<uint16_t> ids = world.scene->classes();
  ids.push_back(kSkyClass);
  std::sort(ids.begin(), ids.end());
  nlohmann::json classes = nlohmann::json::array();
  for (uint16_t id : ids) {
    const FineClass* c = find_fine_class(id);
    classes.push_back(
        {{"id", id}, {"name", c ? std::string(c->name) : "unknown"}, {"lidar_points", summary.points_per_class[id]}});
  }
  return classes;
}

}  // namespace

std::string camera_frame_stem(std::size_t frame, int64_t stamp_ms) {
  return fmt::format("frame{:06d}-{}_{:03d}", frame, stamp_ms / 1000, stamp_ms % 1000);
}

SynthSummary write_synthetic_sequence(const SynthConfig& config, const fs::path& out, bool overwrite,
                                      const SynthProgress& progress) {
  const SynthWorld world = build_synthetic_world(config);
  const bool swept = config.lidar_sweep_s > 0.0;
  prepare_output(out, overwrite, swept);
  const std::size_t scans = world.scan_stamps.size(), images = world.camera_stamps_ms.size();

  std::string poses, times;
  for (std::size_t i = 0; i < scans; ++i) {
    poses += pose_line(world.scan_poses[i]);
    times += fmt::format("{:.6f}\n", world.scan_stamps[i]);
  }
  write_text(out / "poses.txt", poses);
  write_text(out / "times.txt", times);
  const CameraModel& cam = world.camera;
  const auto& k = cam.distortion;
  write_text(out / "camera_info.txt", fmt::format("{:.6f} {:.6f} {:.6f} {:.6f}\n{} {} {} {} {}\n", cam.fx, cam.fy,
                                                  cam.cx, cam.cy, k[0], k[1], k[2], k[3], k[4]));
  write_text(out / "transforms.yaml", transforms_yaml(world.T_lidar_camera));

  const std::vector<Vec3d> rays = config.lidar.ray_directions();
  const CameraSimulator camera(world.camera);
  const std::vector<int> jpeg_params = {cv::IMWRITE_JPEG_QUALITY, config.jpeg_quality};
  SynthSummary summary;
  summary.scans = scans;
  summary.images = images;
  summary.path_length_m = world.path_length_m;
  summary.loop_perimeter_m = world.trajectory.path().perimeter();
  std::mutex mutex;
  std::size_t done = 0;
  tbb::parallel_for(std::size_t{0}, scans + images, [&](std::size_t task) {
    std::array<std::size_t, 256> per_class{};
    std::size_t points = 0, no_returns = 0;
    if (task < scans) {
      const double stamp = world.scan_stamps[task];
      const SimulatedScan scan =
          swept ? simulate_swept_scan(*world.scene, config.lidar, rays,
                                      [&](double t) { return world.T_world_lidar(stamp + t); }, config.lidar_sweep_s,
                                      config.sensor_seed(), task, config.keep_no_return)
                : simulate_scan(*world.scene, config.lidar, rays, world.scan_poses[task], config.sensor_seed(), task,
                                config.keep_no_return);
      const std::string stem = fmt::format("{:06d}", task);
      if (swept) {
        std::vector<uint32_t> ns(scan.times.size());
        for (std::size_t i = 0; i < ns.size(); ++i) ns[i] = static_cast<uint32_t>(std::lround(scan.times[i] * 1e9));
        write_bytes(out / kPointTimesDir / (stem + ".bin"), ns.data(), ns.size() * sizeof(uint32_t));
      }
      write_bytes(out / kLidarDir / (stem + ".bin"), scan.points.data(), scan.points.size() * sizeof(Eigen::Vector4f));
      const std::vector<uint32_t> labels(scan.labels.begin(), scan.labels.end());
      write_bytes(out / kLidarLabelDir / (stem + ".label"), labels.data(), labels.size() * sizeof(uint32_t));
      for (std::size_t i = 0; i < scan.labels.size(); ++i)
        if (scan.points[i].head<3>().squaredNorm() > 0.0f) ++per_class[scan.labels[i]];
      points = scan.points.size();
      no_returns = scan.no_returns;
    } else {
      const std::size_t frame = task - scans;
      const int64_t ms = world.camera_stamps_ms[frame];
      RenderOptions render_options;
      render_options.view_geometry = config.view_geometry;
      render_options.appearance_seed = config.seed;
      const RenderedFrame rendered = camera.render(*world.scene, world.T_world_camera_true(ms / 1000.0),
                                                   config.camera_max_range_m, render_options);
      const std::string stem = camera_frame_stem(frame, ms);
      write_image(out / kImageDir / (stem + ".jpg"), rendered.bgr, jpeg_params);
      write_image(out / kImageLabelDir / (stem + ".png"), rendered.labels, {});
      if (config.view_geometry) {  // at half the image size: the encoder reads it at the feature size
        cv::Mat half;
        cv::resize(rendered.view, half, cv::Size((rendered.view.cols + 1) / 2, (rendered.view.rows + 1) / 2), 0, 0,
                   cv::INTER_NEAREST);
        write_image(out / kRellisSimViewDir / (stem + ".png"), half, {cv::IMWRITE_PNG_COMPRESSION, 6});
      }
    }
    const std::lock_guard lock(mutex);
    for (std::size_t c = 0; c < per_class.size(); ++c) summary.points_per_class[c] += per_class[c];
    summary.points += points;
    summary.no_returns += no_returns;
    ++done;
    if (progress) progress(done, scans + images);
  });

  nlohmann::json meta = {
      {"simulated", true},
      {"generator", "slamvdb synth (simulated off-road sequence, RELLIS-3D layout)"},
      {"seed", config.seed},
      {"scene", config.scene == SceneKind::kRepeatedPlaces ? "repeated" : "offroad"},
      {"parameters", config_json(config)},
      {"counts",
       {{"scans", scans},
        {"images", images},
        {"points_written", summary.points},
        {"no_return_rays", summary.no_returns},
        {"no_returns_written_as_zero_points", config.keep_no_return}}},
      {"path_length_m", summary.path_length_m},
      {"loop_perimeter_m", summary.loop_perimeter_m},
      {"first_scan_stamp", world.scan_stamps.front()},
      {"last_scan_stamp", world.scan_stamps.back()},
      {"classes", class_list(world, summary)},
      {"image_size", {world.camera.width, world.camera.height}},
      {"notes",
       {"LiDAR points are column-major like RELLIS-3D's OS1 files: ray = column * beams + beam; dropped no-return "
        "rays leave gaps in that order",
        config.lidar_sweep_s > 0.0
            ? fmt::format("SIMULATED sweep: each scan is swept over {} s from its stamp, column c at {} s x c / "
                          "columns from the pose at that time (motion distortion as a spinning LiDAR has it); "
                          "os1_cloud_node_point_times/ holds each point's time (uint32 ns since the stamp)",
                          config.lidar_sweep_s, config.lidar_sweep_s)
            : std::string("each scan is cast from the pose at its stamp (no motion distortion within the sweep)"),
        "the LiDAR is mounted turned 180 deg about z (x backwards) like RELLIS-3D's OS1; the camera looks along its -x",
        "intensity is on RELLIS-3D's scale (raw / 65535, about 0..0.012)",
        "camera stamps are whole milliseconds, offset and jittered so none equals a scan stamp",
        "poses are ground truth T_world_lidar; world z is up",
        "all objects are static (vehicles and people do not move)",
        "RGB colours are a natural-looking palette, not the RELLIS-3D label colours",
        "SIMULATED rig errors: images are rendered from the camera at the true extrinsic (transforms.yaml moved by "
        "rig_translation_error_m and rig_rotation_error_deg, in directions drawn from the seed) at the true capture "
        "time (the file name's stamp plus rig_time_offset_s); the files carry the nominal values",
        "pylon_camera_node_sim_view/ (not in RELLIS-3D): SIMULATED per-pixel view geometry for the simulated "
        "encoder, 16-bit 3 channels: range in cm, cosine of the incidence angle x 65535, world-fixed appearance "
        "value as 32768 + 8192 x value"}},
      {"rig",
       {{"T_lidar_camera_true", nlohmann::json::array()},
        {"translation_error_m", config.rig_translation_error_m},
        {"rotation_error_deg", config.rig_rotation_error_deg},
        {"time_offset_s", config.rig_time_offset_s}}}};
  {
    const Eigen::Matrix4d T = world.T_lidar_camera_true.matrix();
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 4; ++c) meta["rig"]["T_lidar_camera_true"].push_back(T(r, c));
  }
  write_text(out / "synth.json", meta.dump(2) + "\n");
  if (!config.view_geometry) {
    std::error_code view_ec;
    fs::remove(out / kRellisSimViewDir, view_ec);  // created empty by prepare_output
  }
  sync_file_system(out);  // everything durable before the sequence is declared complete
  std::error_code ec;
  if (!fs::remove(out / kIncompleteMarker, ec) || ec)
    throw Error(fmt::format("cannot remove {}: {}", (out / kIncompleteMarker).string(), ec.message()));
  sync_directory(out);

  for (const char* dir : {kLidarDir, kLidarLabelDir, kImageDir, kImageLabelDir, kRellisSimViewDir.data(), kPointTimesDir})
    if (fs::is_directory(out / dir, ec))
      for (const auto& entry : fs::directory_iterator(out / dir)) summary.bytes += entry.file_size();
  for (const char* file : kTopFiles) summary.bytes += fs::file_size(out / file);
  return summary;
}

}  // namespace slamvdb::synth
