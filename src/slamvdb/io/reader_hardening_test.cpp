// Hostile and damaged inputs for every reader: FIFOs and directories where files belong,
// non-finite poses and transforms, decompression bombs, images of the wrong size, broken headers.
// Each must be a clear Error naming the file (or a counted skip), never a hang or a silent change.
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/model_manifest.hpp"
#include "slamvdb/io/image_io.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/io/rellis_reader.hpp"
#include "slamvdb/io/scan_io.hpp"
#include "slamvdb/io/sequence_reader.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"
#include "slamvdb/testing/tiny_rellis.hpp"

namespace slamvdb {
namespace {

namespace fs = std::filesystem;
using testing::error_of;
using testing::has_note;
using testing::TempDir;
using testing::TinyRellis;

void expect_mentions(const std::string& message, std::initializer_list<const char*> parts) {
  for (const char* part : parts) EXPECT_NE(message.find(part), std::string::npos) << "'" << part << "' in: " << message;
}

void replace_with_fifo(const fs::path& file) {
  fs::remove(file);
  ASSERT_EQ(::mkfifo(file.c_str(), 0600), 0) << file;
}

// The 24 bytes of a PNG header claiming `width` x `height`, then garbage instead of pixels: a
// reader that decoded it would fail differently, and a real 30000 x 30000 bomb takes too long to make.
std::string png_header(uint32_t width, uint32_t height) {
  std::string h("\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR", 16);
  for (uint32_t v : {width, height})
    for (int shift = 24; shift >= 0; shift -= 8) h.push_back(static_cast<char>((v >> shift) & 0xff));
  return h + std::string(1000, '\x55');
}

// A JPEG SOI + SOF0 claiming `width` x `height`.
std::string jpeg_header(uint32_t width, uint32_t height) {
  std::string h("\xff\xd8\xff\xc0\x00\x11\x08", 7);
  for (uint32_t v : {height, width}) {
    h.push_back(static_cast<char>(v >> 8));
    h.push_back(static_cast<char>(v & 0xff));
  }
  return h + std::string(1000, '\x55');
}

TEST(ReaderHardening, FifosWhereFilesBelongAreErrorsNotHangs) {
  for (const char* name : {"times.txt", "poses.txt", "transforms.yaml", "camera_info.txt"}) {
    TempDir tmp;
    TinyRellis layout;
    layout.times = {5.0, 5.1, 5.2};
    layout.write(tmp.path);
    replace_with_fifo(tmp.path / name);
    expect_mentions(error_of([&] { read_sequence(tmp.path); }), {name, "FIFO"});
  }
  TempDir tmp;
  TinyRellis{}.write(tmp.path);
  const fs::path scan = tmp.path / "os1_cloud_node_kitti_bin" / "000001.bin";
  replace_with_fifo(scan);
  // A scan that is a FIFO is named when the folder is listed (it would otherwise be silently left out).
  expect_mentions(error_of([&] { read_sequence(tmp.path); }), {"000001.bin", "FIFO"});
  expect_mentions(error_of([&] { read_scan({0, scan, {}}); }), {"000001.bin", "FIFO"});
  const fs::path labels = tmp.path / "os1_cloud_node_semantickitti_label_id" / "000000.label";
  replace_with_fifo(labels);
  expect_mentions(
      error_of([&] { read_scan({0, tmp.path / "os1_cloud_node_kitti_bin" / "000000.bin", labels}); }),
      {"000000.label", "FIFO"});
  replace_with_fifo(tmp.path / "features.npy");
  expect_mentions(error_of([&] { read_feature_npy(tmp.path / "features.npy"); }), {"features.npy", "FIFO"});
  replace_with_fifo(tmp.path / "model.json");
  expect_mentions(error_of([&] { load_model_manifest(tmp.path / "model.pt"); }), {"model.json", "FIFO"});
  fs::create_directories(tmp.path / "dir.npy");
  expect_mentions(error_of([&] { read_feature_npy(tmp.path / "dir.npy"); }), {"dir.npy", "directory"});
}

TEST(ReaderHardening, NonFiniteExtrinsicsAreErrorsWithFileAndLine) {
  TempDir tmp;
  TinyRellis{}.write(tmp.path);
  const fs::path yaml = tmp.path / "transforms.yaml";
  // Before: a NaN quaternion passed the unit-norm check (NaN > 1e-3 is false) and gave a map with
  // 0 semantic voxels and exit code 0.
  std::ofstream(yaml) << "os1_cloud_node-pylon_camera_node:\n  q:\n    w: .nan\n    x: 0\n    y: 0\n    z: 0\n"
                         "  t: {x: 0, y: 0, z: 0}\n";
  expect_mentions(error_of([&] { read_rellis_transforms(yaml); }), {"transforms.yaml:3", "q.w", "finite"});
  std::ofstream(yaml) << "os1_cloud_node-pylon_camera_node:\n  q: {w: 1, x: 0, y: 0, z: 0}\n"
                         "  t: {x: 0, y: -.inf, z: 0}\n";
  expect_mentions(error_of([&] { read_rellis_transforms(yaml); }), {"transforms.yaml:3", "t.y", "-.inf"});
  std::ofstream(yaml) << "os1_cloud_node-pylon_camera_node:\n  q: {w: 1, x: 0, y: 0, z: 0}\n  t: {x: 0, y: 1e999, z: 0}\n";
  expect_mentions(error_of([&] { read_rellis_transforms(yaml); }), {"t.y", "finite"});
  std::ofstream(yaml) << "os1_cloud_node-pylon_camera_node:\n  q: [1, 0, 0, 0]\n  t: {x: 0, y: 0, z: 0}\n";
  expect_mentions(error_of([&] { read_rellis_transforms(yaml); }), {"'q' (w x y z)"});
  std::ofstream(yaml) << "- just\n- a list\n";
  expect_mentions(error_of([&] { read_rellis_transforms(yaml); }), {"transforms.yaml", "mapping"});
}

TEST(ReaderHardening, NonFinitePosesAndStampsAreErrorsWithFileAndLine) {
  TempDir tmp;
  std::ofstream(tmp.path / "poses.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n\n1 0 0 nan 0 1 0 0 0 0 1 0\n";
  expect_mentions(error_of([&] { read_kitti_poses(tmp.path / "poses.txt"); }), {"poses.txt:3", "'nan'", "finite"});
  std::ofstream(tmp.path / "poses.txt") << "1 0 0 1e400 0 1 0 0 0 0 1 0\n";
  expect_mentions(error_of([&] { read_kitti_poses(tmp.path / "poses.txt"); }), {"poses.txt:1", "1e400"});
  // Finite but absurd: 4.3e9 m overflowed the 32-bit voxel keys (found by the damage property test).
  std::ofstream(tmp.path / "poses.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 4294967296 0 1 0 0 0 0 1 0\n";
  expect_mentions(error_of([&] { read_kitti_poses(tmp.path / "poses.txt"); }), {"poses.txt:2", "10000 km"});
  std::ofstream(tmp.path / "times.txt") << "0.1\ninf\n";
  expect_mentions(error_of([&] { read_stamps(tmp.path / "times.txt"); }), {"times.txt:2", "'inf'"});
  // A token quoted from the file is cut and its control characters escaped.
  std::ofstream(tmp.path / "times.txt") << "0.1\n\x1b[2J" << std::string(5000, 'x') << "\n";
  const std::string e = error_of([&] { read_stamps(tmp.path / "times.txt"); });
  expect_mentions(e, {"times.txt:2", "\\x1b[2J", "more bytes"});
  EXPECT_LT(e.size(), 300u);
  std::string many;
  for (int i = 0; i < 100; ++i) many += "1 ";
  std::ofstream(tmp.path / "poses.txt") << many << "\n";
  expect_mentions(error_of([&] { read_kitti_poses(tmp.path / "poses.txt"); }), {"poses.txt:1", "more than 64"});
}

TEST(ReaderHardening, ImagesAreSizedFromTheirHeadersBeforeDecoding) {
  TempDir tmp;
  std::ofstream(tmp.path / "bomb.png", std::ios::binary) << png_header(30000, 30000);
  std::ofstream(tmp.path / "bomb.jpg", std::ios::binary) << jpeg_header(65535, 65535);
  EXPECT_EQ(read_image_size(tmp.path / "bomb.png"), cv::Size(30000, 30000));
  EXPECT_EQ(read_image_size(tmp.path / "bomb.jpg"), cv::Size(65535, 65535));
  // Before: decoded, 1.1 GB as a label image and 5.5 GB as a camera image.
  expect_mentions(error_of([&] { load_image_frame({0, {}, tmp.path / "bomb.png", {}}, false, true); }),
                  {"label image", "bomb.png", "30000 x 30000", "900.0 megapixels", "limit of 100"});
  expect_mentions(error_of([&] { load_image_frame({0, tmp.path / "bomb.jpg", {}, {}}, true, false); }),
                  {"camera image", "bomb.jpg", "65535 x 65535"});
  // The limit is configurable.
  expect_mentions(error_of([&] { load_image_frame({0, {}, tmp.path / "bomb.png", {}}, false, true, 1'000'000'000); }),
                  {"cannot decode", "bomb.png"});

  // Damaged headers: zero sizes, truncated, IHDR missing, JPEG without a frame.
  EXPECT_FALSE(parse_image_header(png_header(0, 10)));
  EXPECT_FALSE(parse_image_header(png_header(10, 0x80000000u)));
  EXPECT_FALSE(parse_image_header(png_header(10, 10).substr(0, 20)));
  EXPECT_FALSE(parse_image_header(std::string("\xff\xd8\xff\xd9", 4)));
  EXPECT_FALSE(parse_image_header(jpeg_header(0, 10)));
  EXPECT_FALSE(parse_image_header(""));
  std::string no_ihdr = png_header(10, 10);
  no_ihdr[12] = 'X';
  EXPECT_FALSE(parse_image_header(no_ihdr));
}

TEST(ReaderHardening, JpegSizeIsFoundBehindOtherSegmentsAndFillBytes) {
  std::vector<uchar> encoded;
  ASSERT_TRUE(cv::imencode(".jpg", cv::Mat(37, 53, CV_8UC3, cv::Scalar(1, 2, 3)), encoded));
  std::string jpeg(encoded.begin(), encoded.end());
  // An APP1 segment of 3000 bytes and fill bytes before the next marker, after SOI.
  std::string app1("\xff\xe1", 2);
  app1.push_back(static_cast<char>(3002 >> 8));
  app1.push_back(static_cast<char>(3002 & 0xff));
  app1 += std::string(3000, 'e');
  app1 += "\xff\xff";
  jpeg.insert(2, app1);
  EXPECT_EQ(parse_image_header(jpeg), cv::Size(53, 37));
  TempDir tmp;
  std::ofstream(tmp.path / "a.jpg", std::ios::binary) << jpeg;
  EXPECT_EQ(load_image_frame({0, tmp.path / "a.jpg", {}, {}, {}, 53, 37}, true, false).rgb.size(), cv::Size(53, 37));
}

TEST(ReaderHardening, ImagesOfTheWrongSizeAreRefusedNotResized) {
  TempDir tmp;
  TinyRellis{}.write(tmp.path);  // 32 x 24 images
  const fs::path label = tmp.path / "pylon_camera_node_label_id" / "frame000001-1000_6.png";
  cv::imwrite(label.string(), cv::Mat(12, 16, CV_8UC1, cv::Scalar(3)));
  const Sequence seq = read_sequence(tmp.path);
  ASSERT_EQ(seq.images.size(), 2u);
  EXPECT_EQ(seq.images[1].width, 32);
  EXPECT_EQ(seq.images[1].height, 24);
  EXPECT_EQ(load_image_frame(seq.images[0], true, true).labels.size(), cv::Size(32, 24));
  // Before: silently resized by the simulated encoder. Now an Error for that frame, which the
  // pipeline counts and reports as a skipped image.
  expect_mentions(error_of([&] { load_image_frame(seq.images[1], false, true); }),
                  {"frame000001-1000_6.png", "16 x 12", "32 x 24", "not resized"});
}

TEST(ReaderHardening, ADamagedFirstImageDoesNotChangeTheCamera) {
  TempDir tmp;
  TinyRellis layout;
  layout.images = {{0, "1000_5"}, {1, "1000_6"}, {2, "1000_7"}};
  layout.write(tmp.path);
  const fs::path first = tmp.path / "pylon_camera_node" / "frame000000-1000_5.jpg";
  std::ofstream(first, std::ios::binary) << jpeg_header(65535, 65535);
  // Before: the first image's header alone set the camera size to 65535 x 65535.
  const Sequence seq = read_sequence(tmp.path);
  EXPECT_EQ(seq.camera.width, 32);
  EXPECT_EQ(seq.camera.height, 24);
  EXPECT_TRUE(has_note(seq, "1 of 3 camera images")) << seq.notes.size();
  EXPECT_TRUE(has_note(seq, "65535 x 65535"));
  expect_mentions(error_of([&] { load_image_frame(seq.images[0], true, false); }), {"frame000000", "65535 x 65535"});
  // A camera whose images are all above the limit is refused before any work.
  ReadOptions small;
  small.max_image_pixels = 100;
  expect_mentions(error_of([&] { read_sequence(tmp.path, small); }), {"camera images", "32 x 24", "--max-image-pixels"});
}

TEST(ReaderHardening, NpyHeadersWithMissingValuesNameTheFile) {
  TempDir tmp;
  const auto write_npy = [&](const std::string& dict) {
    std::string header = dict;
    std::ofstream out(tmp.path / "f.npy", std::ios::binary);
    out << "\x93NUMPY" << '\x01' << '\x00' << static_cast<char>(header.size()) << '\x00' << header;
  };
  // Before: a raw "basic_string::substr" out_of_range with no file name (exit code 2).
  write_npy("{'descr':");
  expect_mentions(error_of([&] { read_feature_npy(tmp.path / "f.npy"); }), {"f.npy", "no value for 'descr'"});
  write_npy("{'descr': , 'fortran_order': False, 'shape': (1, 1, 1), }");
  expect_mentions(error_of([&] { read_feature_npy(tmp.path / "f.npy"); }), {"f.npy", "empty value for 'descr'"});
  write_npy("{'descr': '', 'fortran_order': False, 'shape': (1, 1, 1), }");
  expect_mentions(error_of([&] { read_feature_npy(tmp.path / "f.npy"); }), {"f.npy", "dtype ''"});
  write_npy("{'descr': '<f4', 'fortran_order': False, 'shape':");
  expect_mentions(error_of([&] { read_feature_npy(tmp.path / "f.npy"); }), {"f.npy", "'shape'"});
  write_npy("{'descr': '\x1b[31m', 'fortran_order': False, 'shape': (1, 1, 1), }");
  expect_mentions(error_of([&] { read_feature_npy(tmp.path / "f.npy"); }), {"f.npy", "\\x1b[31m"});
}

TEST(ReaderHardening, IncompleteSequencesAreRefused) {
  TempDir tmp;
  TinyRellis{}.write(tmp.path);
  std::ofstream(tmp.path / std::string(kIncompleteMarker)) << "writer killed";
  expect_mentions(error_of([&] { read_sequence(tmp.path); }), {"incomplete", std::string(kIncompleteMarker).c_str()});
}

TEST(ReaderHardening, EntriesThatAreNotFilesAreNamedWhenListing) {
  TempDir tmp;
  fs::create_directories(tmp.path / "000001.bin");
  expect_mentions(error_of([&] { list_files(tmp.path, ".bin"); }), {"000001.bin", "directory"});
  fs::remove(tmp.path / "000001.bin");
  fs::create_symlink(tmp.path / "missing", tmp.path / "000002.bin");
  expect_mentions(error_of([&] { list_files(tmp.path, ".bin"); }), {"000002.bin", "dangling"});
}

}  // namespace
}  // namespace slamvdb
