// Writes the seed corpora of the fuzz harnesses: small valid inputs of every format, made by the
// project's own writers where it has them (so the seeds follow the formats as they change).
// Usage: fuzz_make_seeds OUT_DIR   ->  OUT_DIR/<harness name>/<seed files>
#include <fmt/format.h>

#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sqlite3.h>
#include <string>
#include <vector>

#include "slamvdb/io/npy.hpp"
#include "slamvdb/io/pcd.hpp"
#include "slamvdb/query/query_set.hpp"
#include "slamvdb/store/map_rows.hpp"
#include "slamvdb/store/map_store.hpp"

namespace fs = std::filesystem;

// ros_seeds.cpp: the ROS message and ROS 1 bag seeds.
void write_ros_seeds(const std::function<void(const std::string&, const std::string&, const std::string&)>& seed);
void write_recording_seeds(const fs::path& out_dir);  // make_seeds_recording.cpp

namespace {

fs::path out_dir;

void seed(const std::string& harness, const std::string& name, const std::string& bytes) {
  fs::create_directories(out_dir / harness);
  std::ofstream(out_dir / harness / name, std::ios::binary) << bytes;
}

std::string file_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

template <typename T>
std::string raw(const std::vector<T>& v) {
  return std::string(reinterpret_cast<const char*>(v.data()), v.size() * sizeof(T));
}

std::string encode(const char* ext, const cv::Mat& image) {
  std::vector<uchar> bytes;
  cv::imencode(ext, image, bytes);
  return raw(bytes);
}

// A format-3 map file made format 2 in place: the statistics columns dropped, version 2.
bool format_2_map_file(const fs::path& file) {
  sqlite3* db = nullptr;
  bool ok = sqlite3_open(file.c_str(), &db) == SQLITE_OK;
  for (const char* sql : {"ALTER TABLE semantics DROP COLUMN stats_crc", "ALTER TABLE semantics DROP COLUMN stats",
                          "PRAGMA user_version = 2"})
    if (ok && sqlite3_exec(db, sql, nullptr, nullptr, nullptr) != SQLITE_OK) {
      std::fprintf(stderr, "%s: %s: %s\n", file.c_str(), sql, sqlite3_errmsg(db));
      ok = false;
    }
  sqlite3_close(db);
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUT_DIR\n", argv[0]);
    return 2;
  }
  out_dir = argv[1];
  fs::create_directories(out_dir);

  // scan: 2 bytes (big-endian) = size of the .bin part, then .bin, then .label.
  const std::vector<float> points = {1, 2, 3, 0.1f, 0, 0, 0, 0, -4, 5, 0.5f, 0.01f, 0.1f, 0.1f, 0.1f, 0};
  const std::vector<uint32_t> labels = {3, 0, 0x10004, 7};
  const std::string bin = raw(points);
  seed("scan", "with_labels", std::string{0, static_cast<char>(bin.size())} + bin + raw(labels));
  seed("scan", "without_labels", std::string{'\xff', '\xff'} + bin);

  // npy: float32 and float16 C x H x W, through the project's writer (float16 by hand).
  const std::vector<float> chw = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12};
  slamvdb::write_npy_array(out_dir / "f32.npy.tmp", chw.data(), {3, 2, 2});
  seed("npy", "f32_3x2x2", file_bytes(out_dir / "f32.npy.tmp"));
  slamvdb::write_npy_array(out_dir / "f32.npy.tmp", chw.data(), {1, 2, 3, 2});
  seed("npy", "f32_1x2x3x2", file_bytes(out_dir / "f32.npy.tmp"));
  fs::remove(out_dir / "f32.npy.tmp");
  std::string f16_header = "{'descr': '<f2', 'fortran_order': False, 'shape': (2, 1, 2), }";
  f16_header.append((64 - (10 + f16_header.size() + 1) % 64) % 64, ' ');
  f16_header.push_back('\n');
  seed("npy", "f16_2x1x2",
       std::string("\x93NUMPY\x01\x00", 8) + static_cast<char>(f16_header.size()) + '\0' + f16_header +
           std::string("\x00\x3c\x00\x40\x00\x42\x00\xbc", 8));

  seed("poses_kitti", "two", "1 0 0 0 0 1 0 0 0 0 1 0\n0 -1 0 4.5 1 0 0 -5e-1 0 0 1 6\n");
  seed("poses_kitti", "exp", "1.000000000e+00 0.0 0.0 1.2e3 0 1 0 0 0 0 1 0\r\n\n");
  seed("times", "stamps", "0.0\n0.1\n0.2\n1700000000.250000\n");
  seed("camera_info", "pinhole", "2813.643275 2808.326079 969.285772 624.049972\n");
  seed("camera_info", "plumb_bob", "400 400 320 200\n-0.134313 -0.025905 0.002181 0.00084 0.0\n");
  seed("transforms", "block",
       "os1_cloud_node-pylon_camera_node:\n  q:\n    w: -0.50507811\n    x: 0.51206185\n    y: 0.49024953\n"
       "    z: -0.49228464\n  t:\n    x: -0.13165462\n    y: 0.03870398\n    z: -0.17253834\n");
  seed("transforms", "flow",
       "os1_cloud_node-pylon_camera_node: {q: {w: 1, x: 0, y: 0, z: 0}, t: {x: 0.1, y: 0.2, z: 0.3}}\n");
  seed("kitti_calib", "calib",
       "P0: 7.188560e+02 0 6.071928e+02 0 0 7.188560e+02 1.852157e+02 0 0 0 1 0\n"
       "P2: 7.188560e+02 0 6.071928e+02 4.538225e+01 0 7.188560e+02 1.852157e+02 -1.130887e-01 0 0 1 3.779761e-03\n"
       "Tr: 4.276802e-04 -9.999672e-01 -8.084491e-03 -1.198459e-02 -7.210626e-03 8.081198e-03 -9.999413e-01 "
       "-5.403984e-02 9.999738e-01 4.859485e-04 -7.206933e-03 -2.921968e-01\n");

  // Images: tiny JPEG (colour) and PNGs (grey labels, colour), encoded by OpenCV.
  cv::Mat colour(12, 20, CV_8UC3, cv::Scalar(10, 200, 30)), grey(12, 20, CV_8UC1, cv::Scalar(3));
  cv::circle(colour, {10, 6}, 4, cv::Scalar(250, 0, 0), -1);
  seed("image", "colour.jpg", encode(".jpg", colour));
  seed("image", "colour.png", encode(".png", colour));
  seed("image", "labels.png", encode(".png", grey));

  seed("model_manifest", "dense",
       R"({"manifest_version": 1, "kind": "dense_image", "model_id": "lseg-test",
  "input": {"height": 32, "width": 48, "resize": "resize_short_center_crop", "interpolation": "bilinear",
            "channel_order": "RGB", "value_scale": 0.00392156862745098, "mean": [0.5, 0.5, 0.5], "std": [0.5, 0.5, 0.5]},
  "output": {"dim": 8, "height": 16, "width": 24, "layout": "CHW", "l2_normalized": false, "normalize_output": true},
  "runtime": {"threads": 2, "batch_size": 4}})");
  seed("model_manifest", "text",
       R"({"manifest_version": 1, "kind": "text", "model_id": "clip-text-test",
  "text": {"context_length": 77, "vocab": "bpe_simple_vocab_16e6.txt.gz"},
  "output": {"dim": 8, "l2_normalized": true, "normalize_output": false}})");
  seed("poses_tum", "tum", "# stamp tx ty tz qx qy qz qw\n0.0 1 2 3 0 0 0 1\n0.1 1.5 2 3 0 0 0.7071068 0.7071068\n");
  seed("poses_tum", "kitti", "1 0 0 0 0 1 0 0 0 0 1 0\n");
  seed("points", "commas", "x,y,z\n1.5,-2,0.25\n\"3\",\"4\",\"5e2\"\n");
  seed("points", "blanks", "\xEF\xBB\xBF" "10 20 30\r\n-5.625\t15.125\t-1.875\r\n\n");
  seed("server_requests", "text", R"({"text": ["tall grass", "dirt"], "not": "puddle", "top_k": 7})");
  seed("server_requests", "vector", R"({"vector": [[1, 0, 0, 0], [0, 1, 0.5, 0]], "not_vector": [0, 0, 1, 0], "top_k": 0, "threshold": 0.25, "exact": true})");
  seed("server_requests", "class", R"({"class": "smooth", "not_class": ["rough"], "threshold": -0.5})");
  seed("server_requests", "image", R"({"image": ["iVBORw0KGgoAAAANSUhEUgAAAAEAAAABCAAAAAA6fptVAAAACklEQVR4nGNgAAAAAgAB4iG8MwAAAABJRU5ErkJggg==", "data:image/png;base64,/9j/4AAQSkZJRg"], "text": "grass", "top_k": 3})");
  seed("server_requests", "classes", "?bbox=-2,-2,-1,2,2,1&min_confidence=0.5");
  seed("server_requests", "nav_grid", "?near=0,0&radius=3&resolution=0.5&format=png&robot_height=1.2&min_confidence=0.1");
  seed("server_requests", "points", "?bbox=-2,-2,-1,2,2,1&lod=2&limit=5000&query=tall%20grass");
  seed("fleet_rows", "pose", std::string(1, '\0') + "{0.5,-0.8660254037844386,0,12.25,0.8660254037844386,0.5,0,-3,0,0,1,1e+2,0,0,0,1}");
  seed("fleet_rows", "centroid", std::string(1, '\1') + "{0.70710677,-0.70710677,0,1.5e-05}");
  // The catalog's rows as PostgreSQL prints them (COPY text: '\t' between fields, "\N" NULL): two
  // sessions (one without a time range) and three submaps, then region rows with and without a summary.
  seed("fleet_catalog_rows", "catalog",
       std::string(1, '\0') +
           "1\tmonday\trobot-a\tSIMULATED drive\t0\t12.5\t{1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1}\n"
           "2\ttuesday\t\t\t\\N\t\\N\t{0,-1,0,3,1,0,0,4,0,0,1,0,0,0,0,1}\n"
           "\\.\n"
           "1\t0\t{1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1}\t0\t6.25\t12.5\t4\t4096\t812\t800\t1\t0\t0\t-0.5\t10\t10\t1.5\n"
           "1\t1\t{1,0,0,100,0,1,0,0,0,0,1,0,0,0,0,1}\t6.25\t12.5\t12.5\t4\t4096\t812\t800\t2\t100\t0\t-0.5\t110\t10\t1.5\n"
           "2\t0\t{1,0,0,0,0,1,0,0,0,0,1,0,0,0,0,1}\t\\N\t\\N\t0\t0\t0\t0\t0\t1\t3\t4\t0\t3\t4\t0\n");
  seed("fleet_catalog_rows", "region",
       std::string(1, '\1') +
           "1\t0\t0\t0\t-0.5\t10\t10\t1.5\t{0.70710677,0,0,0.70710677}\t0.3217505543966422\t800\n"
           "2\t5\t3\t4\t0\t3\t4\t0\t\\N\t\\N\t0\n");
  {  // the fleet row's parameters as `push` writes them: a map's meta entries, all strings
    nlohmann::json entries = nlohmann::json::object();
    slamvdb::MapParams params;
    params.semantic.dim = 8;
    slamvdb::MapInfo info;
    info.model_id = "simulated-clip";
    info.ontology = "rellis";
    for (const auto& [key, value] : slamvdb::store::map_meta(params, info))
      entries[key] = value;
    seed("fleet_rows", "params", std::string(1, '\2') + entries.dump());
  }
  seed("ontology", "coarse", file_bytes(fs::path(SLAMVDB_SOURCE_DIR) / "data/ontology/rellis3d_coarse.yaml"));
  seed("ontology", "fine", file_bytes(fs::path(SLAMVDB_SOURCE_DIR) / "data/ontology/rellis3d_fine.yaml"));

  // PCD: the project's writer in all three encodings.
  slamvdb::PcdCloud cloud;
  cloud.points = {{1, 2, 3}, {-4, 5, 0.5f}, {0.1f, 0.1f, 0.1f}};
  cloud.intensity = {0.1f, 0.2f, 0.3f};
  cloud.time = {0, 0.05f, 0.1f};
  for (const auto& [encoding, name] : {std::pair{slamvdb::PcdEncoding::kAscii, "ascii"},
                                       std::pair{slamvdb::PcdEncoding::kBinary, "binary"},
                                       std::pair{slamvdb::PcdEncoding::kBinaryCompressed, "compressed"}}) {
    slamvdb::write_pcd(out_dir / "seed.pcd.tmp", cloud, encoding);
    seed("pcd", name, file_bytes(out_dir / "seed.pcd.tmp"));
  }
  fs::remove(out_dir / "seed.pcd.tmp");

  // Query set and map file: small valid ones through the project's writers.
  slamvdb::QuerySet q;
  q.model_id = "fuzz-space";
  q.names = {"smooth", "rough"};
  q.vectors = slamvdb::QueryMatrix::Zero(2, 4);
  q.vectors(0, 0) = q.vectors(1, 1) = 1;
  q.colours = {{1, 2, 3}, {4, 5, 6}};
  slamvdb::save_query_set(out_dir / "seed.json.tmp", q);
  seed("query_set", "two", file_bytes(out_dir / "seed.json.tmp"));
  fs::remove(out_dir / "seed.json.tmp");
  slamvdb::MapParams params;
  params.semantic.dim = 4;
  params.submap_length = 2.0;
  slamvdb::SemanticMap map(params,
                          slamvdb::MapInfo{.model_id = "fuzz-space", .ontology = "rellis3d", .source = "seed"});
  for (int i = 0; i < 3; ++i) {  // three short scans: two submaps
    slamvdb::Pose T = slamvdb::Pose::Identity();
    T.translation() = slamvdb::Vec3d(1.5 * i, 0, 1);
    map.integrate_scan(i, {{2, 0, -1}, {2, 0.3f, -1}, {3, 1, 0}}, T);
    map.update_active(i, [](slamvdb::VoxelMap& v, const slamvdb::Pose&, std::span<const slamvdb::PlacedVoxelMap>) {
      const float e[4] = {1, 0, 0.5f, 0};
      v.occupancy().for_each_occupied([&](const slamvdb::VoxelKey& k, float) { v.semantics().integrate(k, e); });
    });
  }
  map.finish_active_submap();
  slamvdb::save_map(out_dir / "seed.svdb.tmp", map);
  seed("map_file", "v3", file_bytes(out_dir / "seed.svdb.tmp"));
  // The same map as format 2 wrote it (no statistics columns): the loader's fallback, which
  // gives every entry weight = count and an unknown spread.
  if (!format_2_map_file(out_dir / "seed.svdb.tmp")) return 1;
  seed("map_file", "v2", file_bytes(out_dir / "seed.svdb.tmp"));
  fs::remove(out_dir / "seed.svdb.tmp");

  write_ros_seeds(seed);

  seed("file_names", "rellis", "frame000104-1581624663_149");
  seed("file_names", "escape", "model\x1b[2J\xc2\x9b\xe2\x80\xae\xff");
  write_recording_seeds(out_dir);
  std::printf("seeds written to %s\n", out_dir.c_str());
  return 0;
}
