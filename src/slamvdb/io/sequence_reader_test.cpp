#include "slamvdb/io/sequence_reader.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>
#include <functional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/temp_dir.hpp"

namespace slamvdb {
namespace {
namespace fs = std::filesystem;

using testing::TempDir;

using testing::error_of;

TEST(SequenceReader, UnknownLayoutErrorListsWhatWasLookedFor) {
  TempDir tmp;
  const std::string message = error_of([&] { read_sequence(tmp.path); });
  EXPECT_NE(message.find("os1_cloud_node_kitti_bin"), std::string::npos) << message;
  EXPECT_NE(message.find("velodyne"), std::string::npos) << message;
  EXPECT_NE(error_of([&] { read_sequence(tmp.path / "nope"); }).find("does not exist"), std::string::npos);
}

TEST(SequenceReader, ParsesNumbersAndNamesTheBadOne) {
  EXPECT_EQ(parse_numbers(" 1 -2.5e1\t3 ", "x"), (std::vector<double>{1, -25, 3}));
  EXPECT_TRUE(parse_numbers("", "x").empty());
  const std::string message = error_of([] { parse_numbers("1 2,5 3", "poses.txt:4"); });
  EXPECT_NE(message.find("poses.txt:4"), std::string::npos) << message;
  EXPECT_NE(message.find("'2,5'"), std::string::npos) << message;
  EXPECT_THROW(parse_numbers("nan", "x"), Error);
}

TEST(SequenceReader, ReadsPosesAndStampsWithClearErrors) {
  TempDir tmp;
  std::ofstream(tmp.path / "poses.txt") << "1 0 0 1 0 1 0 2 0 0 1 3\n\n0 -1 0 4 1 0 0 5 0 0 1 6\n";
  const auto poses = read_kitti_poses(tmp.path / "poses.txt");
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_TRUE(poses[1].translation().isApprox(Vec3d(4, 5, 6)));
  EXPECT_TRUE((poses[1].linear() * Vec3d::UnitX()).isApprox(Vec3d::UnitY()));

  std::ofstream(tmp.path / "short.txt") << "1 0 0 1 0 1 0 2 0 0 1\n";
  EXPECT_NE(error_of([&] { read_kitti_poses(tmp.path / "short.txt"); }).find("11 numbers"), std::string::npos);
  std::ofstream(tmp.path / "scaled.txt") << "2 0 0 1 0 2 0 2 0 0 2 3\n";
  EXPECT_NE(error_of([&] { read_kitti_poses(tmp.path / "scaled.txt"); }).find("rotation"), std::string::npos);

  std::ofstream(tmp.path / "times.txt") << "0.0\n0.1\n0.1\n";
  const std::string message = error_of([&] { read_stamps(tmp.path / "times.txt"); });
  EXPECT_NE(message.find("times.txt"), std::string::npos) << message;
  EXPECT_NE(message.find("stamp 2"), std::string::npos) << message;
}

TEST(SequenceReader, ListsFilesInFrameOrder) {
  TempDir tmp;
  for (const char* name : {"10.bin", "9.bin", "000011.bin", "b.bin", "a.bin", "x.txt"}) std::ofstream(tmp.path / name);
  std::vector<std::string> names;
  for (const auto& p : list_files(tmp.path, ".bin")) names.push_back(p.filename().string());
  EXPECT_EQ(names, (std::vector<std::string>{"9.bin", "10.bin", "000011.bin", "a.bin", "b.bin"}));
  EXPECT_THROW(list_files(tmp.path / "missing", ".bin"), Error);
}

}  // namespace
}  // namespace slamvdb
