// Shared by the TorchScript tests (torch_encoders_test.cpp: the encoders against Python;
// torch_commands_test.cpp: the CLI commands that run them): tools/make_test_models.py builds small
// randomly initialised networks with the real ones' interfaces once per test suite.
#pragma once
#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>

#include "slamvdb/core/error.hpp"
#include "slamvdb/inference/torch_encoders.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/testing/shared_data.hpp"
#include "slamvdb/testing/run_command.hpp"
#include "slamvdb/testing/text_file.hpp"

namespace slamvdb::torch_test {

namespace fs = std::filesystem;
using nlohmann::json;

inline const fs::path kTools = fs::path(SLAMVDB_SOURCE_DIR) / "tools";

// The interpreter CMake found (Debian's, with python3-torch), unless $SLAMVDB_PYTHON names
// another; empty if it cannot import torch and numpy.
inline std::string torch_python() {
  const char* env = std::getenv("SLAMVDB_PYTHON");
  const std::string python = env ? env : SLAMVDB_PYTHON;
  return std::system((python + " -c 'import torch, numpy' >/dev/null 2>&1").c_str()) == 0 ? python : std::string();
}

using testing::quote_path;
using testing::read_text_file;

// A 3 x H x W float array of 0..255 values (as make_test_models.py saves images) as RGB cv::Mat.
inline cv::Mat read_image_npy(const fs::path& p) {
  const FeatureMap planar = read_feature_npy(p);
  cv::Mat rgb(planar.height(), planar.width(), CV_8UC3);
  for (int y = 0; y < planar.height(); ++y)
    for (int x = 0; x < planar.width(); ++x)
      for (int c = 0; c < 3; ++c) rgb.at<cv::Vec3b>(y, x)[c] = static_cast<uint8_t>(planar.pixel(x, y)[c]);
  return rgb;
}

inline ImageFrame frame_of(cv::Mat rgb, std::string source) {
  ImageFrame f;
  f.rgb = std::move(rgb);
  f.source = std::move(source);
  return f;
}

inline float max_abs_diff(const float* a, const float* b, std::size_t n) {
  float worst = 0.0f;
  for (std::size_t i = 0; i < n; ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
  return worst;
}

// `fn()` must throw Error whose message contains every needle.
template <typename Fn>
inline void expect_error(Fn&& fn, std::initializer_list<std::string> needles) {
  try {
    fn();
    ADD_FAILURE() << "no Error thrown";
  } catch (const Error& e) {
    const std::string what = e.what();
    for (const auto& n : needles) EXPECT_NE(what.find(n), std::string::npos) << "'" << n << "' not in: " << what;
  }
}

class TorchEncoders : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    python_ = torch_python();
    if (python_.empty()) return;
    dir_ = fs::temp_directory_path() / ("slamvdb_torch_test_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    const std::string cmd = python_ + " " + quote_path(kTools / "make_test_models.py") + " --out " + quote_path(dir_) +
                            " --vocab " + quote_path(testing::kClipVocab) + " > " + quote_path(dir_ / "make.log") + " 2>&1";
    models_ok_ = std::system(cmd.c_str()) == 0;
  }
  static void TearDownTestSuite() {
    if (!dir_.empty()) fs::remove_all(dir_);
  }
  void SetUp() override {
    if (python_.empty()) GTEST_SKIP() << "no python3 with torch and numpy (set SLAMVDB_PYTHON)";
    ASSERT_TRUE(models_ok_) << "tools/make_test_models.py failed:\n" << read_text_file(dir_ / "make.log");
  }

  static fs::path model(const std::string& name) { return dir_ / (name + ".pt"); }

  // NAME.pt beside a copy of BASE.json changed by `edit`: the same network, another manifest.
  template <typename Edit>
  static fs::path variant(const std::string& base, const std::string& name, Edit&& edit) {
    json manifest = json::parse(read_text_file(dir_ / (base + ".json")));
    edit(manifest);
    std::ofstream(dir_ / (name + ".json")) << manifest.dump(2);
    fs::remove(dir_ / (name + ".pt"));
    fs::create_symlink(dir_ / (base + ".pt"), dir_ / (name + ".pt"));
    return dir_ / (name + ".pt");
  }

  static int run_cli(const std::string& args, const fs::path& stdout_file) {
    return std::system((std::string(SLAMVDB_CLI_PATH) + " " + args + " > " + quote_path(stdout_file) + " 2>&1").c_str());
  }

  static inline std::string python_;
  static inline fs::path dir_;
  static inline bool models_ok_ = false;
};

}  // namespace slamvdb::torch_test
