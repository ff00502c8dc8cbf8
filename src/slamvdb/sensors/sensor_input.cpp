#include "slamvdb/sensors/sensor_input.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <algorithm>

#include "slamvdb/io/scan_source.hpp"
#include "slamvdb/recording/recording.hpp"
#include "slamvdb/sensors/recording_input.hpp"

namespace slamvdb {

namespace {

// A folder's scans and images merged by stamp (a scan before an image of the same stamp), each
// scan file read when its turn comes.
class FolderStream final : public SensorStream {
 public:
  FolderStream(const Sequence& sequence, bool with_images) : seq_(sequence), with_images_(with_images) {}
  bool next(SensorFrame& out) override {
    const bool scan_left = si_ < seq_.scans.size();
    const bool image_left = with_images_ && ii_ < seq_.images.size();
    if (!scan_left && !image_left) return false;
    if (scan_left && (!image_left || seq_.scans[si_].stamp <= seq_.images[ii_].stamp)) {
      const ScanRecord& rec = seq_.scans[si_++];
      out.kind = SensorFrame::Kind::kScan;
      out.stamp = rec.stamp;
      out.name = rec.points.string();
      out.error.clear();
      out.image = {};
      try {
        ScanPoints scan = load_scan_points({rec.stamp, rec.points});
        out.points = std::move(scan.points);
        out.point_times = std::move(scan.time);
      } catch (const Error& e) {
        out.points.clear();
        out.point_times.clear();
        out.error = fmt::format("scan {}: {}", rec.points.filename().string(), e.what());
      }
      return true;
    }
    out.kind = SensorFrame::Kind::kImage;
    out.image = seq_.images[ii_++];
    out.stamp = out.image.stamp;
    out.name = out.image.rgb.empty() ? out.image.labels.string() : out.image.rgb.string();
    out.points.clear();
    out.point_times.clear();
    out.error.clear();
    return true;
  }

 private:
  const Sequence& seq_;
  bool with_images_;
  std::size_t si_ = 0, ii_ = 0;
};

class FolderInput final : public SensorInput {
 public:
  FolderInput(Sequence sequence, std::string kind) {
    sequence_ = std::move(sequence);
    kind_ = std::move(kind);
    has_camera_ = !sequence_.images.empty();
    has_labels_ = std::any_of(sequence_.images.begin(), sequence_.images.end(),
                              [](const ImageRecord& image) { return image.has_labels(); });
    scan_count_ = sequence_.scans.size();
  }
  std::unique_ptr<SensorStream> open(bool with_images) const override {
    return std::make_unique<FolderStream>(sequence_, with_images);
  }
};

}  // namespace

std::unique_ptr<SensorInput> sequence_input(Sequence sequence) {
  std::string layout = sequence.layout;
  return std::make_unique<FolderInput>(std::move(sequence), std::move(layout));
}

std::unique_ptr<SensorInput> open_sensor_input(const std::filesystem::path& path, const InputOptions& options) {
  require_exists(path, "input");
  if (recording::is_recording(path)) return open_recording_input(path, options);
  if (!options.scans_only) return sequence_input(read_sequence(path, options.read));
  // `odometry`: a dataset's scans, or a plain folder of scan files.
  ScanSource source = open_scan_source(path, options.rate_hz);
  Sequence seq;
  seq.root = path;
  seq.layout = source.kind;
  for (const ScanFile& scan : source.scans) seq.scans.push_back({scan.stamp, scan.path, {}});
  seq.poses = std::move(source.ground_truth);
  seq.notes = std::move(source.notes);
  return std::make_unique<FolderInput>(std::move(seq), source.kind);
}

}  // namespace slamvdb
