#pragma once
// For tests only: the data that lives beside the project in ../shared (the real CLIP vocabulary,
// the RELLIS-3D frame), found relative to the source tree and never copied into the repository.
#include <filesystem>

namespace slamvdb::testing {

inline std::filesystem::path shared_dir() { return std::filesystem::path(SLAMVDB_SOURCE_DIR) / ".." / "shared"; }
inline const std::filesystem::path kClipVocab = shared_dir() / "clip" / "bpe_simple_vocab_16e6.txt.gz";

}  // namespace slamvdb::testing
