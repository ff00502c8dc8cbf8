#pragma once
// A test's whole output file as one string (empty when it cannot be read: the test's assertions
// on its content then fail and say so).
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

namespace slamvdb::testing {

inline std::string read_text_file(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

}  // namespace slamvdb::testing
