#pragma once
// For tests only: a tiny RELLIS-3D layout (3 scans of 2 points, 2 camera + label images of 32 x 24,
// poses, camera_info.txt, transforms.yaml, optional times.txt), written by hand so that each test
// can change one thing.
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <utility>
#include <vector>

#include "slamvdb/io/dataset.hpp"

namespace slamvdb::testing {

struct TinyRellis {
  std::vector<int> scans{0, 1, 2};
  std::vector<std::pair<int, std::string>> images{{0, "1000_5"}, {1, "1000_6"}};  // frame, SEC_FRAC
  std::vector<double> times;                                                      // empty: no times.txt
  int poses = 3;
  std::string camera_info = "20 21 16 12\n";

  void write(const std::filesystem::path& dir) const {
    namespace fs = std::filesystem;
    for (const char* sub : {"os1_cloud_node_kitti_bin", "os1_cloud_node_semantickitti_label_id", "pylon_camera_node",
                            "pylon_camera_node_label_id", "features"})
      fs::create_directories(dir / sub);
    for (int n : scans) {
      char stem[16];
      std::snprintf(stem, sizeof(stem), "%06d", n);
      const float xyzi[8] = {1, 2, 3, 0, 4, 5, 6, 0};
      const uint32_t labels[2] = {3, 4};
      std::ofstream(dir / "os1_cloud_node_kitti_bin" / (std::string(stem) + ".bin"), std::ios::binary)
          .write(reinterpret_cast<const char*>(xyzi), sizeof(xyzi));
      std::ofstream(dir / "os1_cloud_node_semantickitti_label_id" / (std::string(stem) + ".label"), std::ios::binary)
          .write(reinterpret_cast<const char*>(labels), sizeof(labels));
    }
    for (const auto& [frame, stamp] : images) {
      char stem[64];
      std::snprintf(stem, sizeof(stem), "frame%06d-%s", frame, stamp.c_str());
      cv::imwrite((dir / "pylon_camera_node" / (std::string(stem) + ".jpg")).string(),
                  cv::Mat(24, 32, CV_8UC3, cv::Scalar(0, 0, 0)));
      cv::imwrite((dir / "pylon_camera_node_label_id" / (std::string(stem) + ".png")).string(),
                  cv::Mat(24, 32, CV_8UC1, cv::Scalar(3)));
    }
    std::ofstream(dir / "camera_info.txt") << camera_info;
    std::ofstream(dir / "transforms.yaml")
        << "os1_cloud_node-pylon_camera_node:\n  q: {w: 0.5, x: -0.5, y: 0.5, z: -0.5}\n"
           "  t: {x: 0.1, y: 0.2, z: 0.3}\n";
    std::ofstream poses_file(dir / "poses.txt");
    for (int i = 0; i < poses; ++i) poses_file << "1 0 0 " << i << " 0 1 0 0 0 0 1 0\n";
    if (!times.empty()) {
      std::ofstream times_file(dir / "times.txt");
      for (double t : times) times_file << t << "\n";
    }
  }
};

inline bool has_note(const Sequence& seq, const std::string& text) {
  for (const auto& note : seq.notes)
    if (note.find(text) != std::string::npos) return true;
  return false;
}

}  // namespace slamvdb::testing
