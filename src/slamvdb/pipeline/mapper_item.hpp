// The Mapper's queued item, shared by its input side (mapper.cpp) and its worker threads
// (mapper_workers.cpp); private to the pipeline part.
#pragma once

#include <fmt/format.h>

#include <chrono>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/pipeline/mapper.hpp"

namespace slamvdb {

struct Mapper::Item {
  enum class State { kWaitingForEncoder, kEncoding, kReady };
  bool is_scan = true;
  double stamp = 0;
  std::vector<Vec3f> points;
  std::optional<ImageRecord> record;  // an image the inference thread still has to encode
  FeatureMap features;
  State state = State::kReady;
  std::string error;  // extraction failed
  std::size_t bytes = 0;

  std::string name() const {
    if (record && !(record->rgb.empty() && record->labels.empty()))
      return fmt::format("image {}", (record->rgb.empty() ? record->labels : record->rgb).filename().string());
    return fmt::format("{} at {:.6f} s", is_scan ? "scan" : "image", stamp);
  }
};

namespace mapper_detail {
using Clock = std::chrono::steady_clock;
inline double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }
}  // namespace mapper_detail

}  // namespace slamvdb
