#pragma once
// For the fuzz harnesses: the input bytes as a file, for readers that take a path.
#include <unistd.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace slamvdb::fuzz {

// One file per process (libFuzzer runs inputs one after the other), rewritten for each input,
// under $TMPDIR; `name` keeps the extension a reader may look at.
inline std::filesystem::path write_input(const uint8_t* data, std::size_t size, const std::string& name) {
  struct Dir {
    std::filesystem::path path =
        std::filesystem::temp_directory_path() / ("slamvdb-fuzz-" + std::to_string(::getpid()));
    Dir() { std::filesystem::create_directories(path); }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  const std::filesystem::path path = dir.path / name;
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (!f || std::fwrite(data, 1, size, f) != size || std::fclose(f) != 0)
    throw std::runtime_error("fuzz harness: cannot write " + path.string());
  return path;
}

}  // namespace slamvdb::fuzz
