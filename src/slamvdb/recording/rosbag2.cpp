// A ROS 2 bag: its files (sqlite3 .db3 or .mcap, possibly zstd-compressed) merged by timestamp.
#include "slamvdb/recording/rosbag2.hpp"

#include <fmt/format.h>
#include <fmt/std.h>
#include <unistd.h>

#include <algorithm>
#include <map>
#include <system_error>

#include "slamvdb/core/error.hpp"
#include "slamvdb/recording/decompress.hpp"
#include "slamvdb/recording/mcap.hpp"
#include "slamvdb/recording/rosbag2_db3.hpp"
#include "slamvdb/recording/rosbag2_metadata.hpp"

namespace slamvdb::recording {

namespace rosbag2_cpp {

class Rosbag2Reader final : public RecordingReader {
 public:
  explicit Rosbag2Reader(const std::filesystem::path& path);
  ~Rosbag2Reader() override;

  std::string describe() const override;
  const std::vector<Channel>& channels() const override { return channels_; }
  std::optional<TimeRange> time_range() const override { return range_; }
  std::uint64_t size_bytes() const override { return size_; }
  void select(const std::set<std::uint32_t>& channel_ids) override;
  bool next(Message& out) override;
  std::uint64_t bytes_read() const override;
  std::vector<std::string> notes() const override;

 private:
  struct Slot {
    Rosbag2File file;
    std::uint64_t size = 0;
    std::unique_ptr<RecordingReader> reader;
    std::map<std::uint32_t, int> channel_of;  // the file's channel id -> ours (-1: not in the metadata)
    Message current;
    bool open = false, done = false;
    std::filesystem::path copy;  // the decompressed copy (FILE compression)
  };
  void open_slot(std::size_t i);
  void close_slot(std::size_t i);
  bool advance(std::size_t i);  // the slot's next message of a selected channel into `current`
  void push(std::size_t i);
  bool later(std::size_t a, std::size_t b) const;
  std::int64_t start_of(std::size_t i) const { return slots_[i].file.start_ns.value_or(INT64_MIN); }
  std::filesystem::path temp_dir();

  std::filesystem::path path_;
  bool folder_ = false;
  std::string storage_ = "sqlite3", compression_mode_;
  std::vector<Channel> channels_;
  std::optional<TimeRange> range_;
  std::uint64_t size_ = 0, finished_bytes_ = 0;
  std::vector<Slot> slots_;
  std::vector<std::size_t> heap_;
  std::size_t next_slot_ = 0;
  std::optional<std::size_t> last_;
  std::set<std::uint32_t> selected_;
  Decompressor decompressor_;
  ByteBuffer message_;
  std::uint64_t delivered_ = 0, zstd_messages_ = 0;
  std::map<std::string, std::uint64_t> unlisted_;  // messages on topics metadata.yaml does not list
  std::filesystem::path temp_dir_;
  std::size_t copies_open_ = 0, max_copies_open_ = 0;
  std::uint64_t copy_bytes_open_ = 0, max_copy_bytes_ = 0;
  std::vector<std::string> notes_;
};

Rosbag2Reader::Rosbag2Reader(const std::filesystem::path& path) : path_(path) {
  std::error_code ec;
  folder_ = std::filesystem::is_directory(path, ec);
  if (folder_) {
    Rosbag2Metadata m = read_rosbag2_metadata(path);
    storage_ = m.storage;
    compression_mode_ = m.compression_mode;
    channels_ = std::move(m.topics);
    range_ = m.range;
    for (Rosbag2File& f : m.files) {
      slots_.emplace_back();
      slots_.back().file = std::move(f);
    }
  } else {
    slots_.emplace_back();
    slots_.back().file = Rosbag2File{path, std::nullopt};
  }
  for (Slot& s : slots_) {
    s.size = std::filesystem::file_size(s.file.path, ec);
    if (ec) throw Error(fmt::format("ROS 2 bag {}: cannot read the size of {}: {}", path, s.file.path, ec.message()));
    size_ += s.size;
  }
  // Files in start-time order (those without one keep their place, opened at once).
  std::stable_sort(slots_.begin(), slots_.end(),
                   [](const Slot& a, const Slot& b) { return a.file.start_ns.value_or(INT64_MIN) < b.file.start_ns.value_or(INT64_MIN); });
  if (!folder_) {
    open_slot(0);
    auto& db3 = static_cast<Db3Reader&>(*slots_[0].reader);
    db3.count_messages();
    channels_ = db3.channels();
    for (const Channel& c : channels_) slots_[0].channel_of[c.id] = static_cast<int>(c.id);
    range_ = db3.time_range();
  }
}

Rosbag2Reader::~Rosbag2Reader() {
  slots_.clear();  // closes the readers before their copies go
  std::error_code ec;
  if (!temp_dir_.empty()) std::filesystem::remove_all(temp_dir_, ec);
}

std::filesystem::path Rosbag2Reader::temp_dir() {
  if (temp_dir_.empty()) {
    std::string pattern = (std::filesystem::temp_directory_path() / "slamvdb-rosbag2-XXXXXX").string();
    if (!::mkdtemp(pattern.data()))
      throw Error(fmt::format("ROS 2 bag {}: cannot create a temporary folder for its decompressed files in {}", path_,
                              std::filesystem::temp_directory_path()));
    temp_dir_ = pattern;
  }
  return temp_dir_;
}

void Rosbag2Reader::open_slot(std::size_t i) {
  Slot& s = slots_[i];
  std::filesystem::path file = s.file.path;
  const std::string display = fmt::format("ROS 2 bag file {}", s.file.path);
  if (compression_mode_ == "FILE") {
    if (file.extension() != ".zstd")
      throw Error(fmt::format("{}: metadata.yaml says the files are zstd-compressed, but its name does not end in .zstd",
                              display));
    s.copy = temp_dir() / file.stem().filename();
    const std::uint64_t bytes = decompress_zstd_file(file, s.copy, "ROS 2 bag file");
    file = s.copy;
    ++copies_open_;
    copy_bytes_open_ += bytes;
    max_copies_open_ = std::max(max_copies_open_, copies_open_);
    max_copy_bytes_ = std::max(max_copy_bytes_, copy_bytes_open_);
  }
  if (storage_ == "mcap")
    s.reader = open_mcap(file);
  else
    s.reader = std::make_unique<Db3Reader>(file, display);
  s.open = true;
  if (folder_) {
    for (const Channel& c : s.reader->channels()) {
      const auto ours = std::find_if(channels_.begin(), channels_.end(),
                                     [&](const Channel& o) { return o.topic == c.topic && o.type == c.type; });
      if (ours != channels_.end() && ours->definition.empty()) ours->definition = c.definition;
      s.channel_of[c.id] = ours == channels_.end() ? -1 : static_cast<int>(ours - channels_.begin());
    }
  }
  if (!selected_.empty()) {
    std::set<std::uint32_t> mine;
    for (const auto& [theirs, ours] : s.channel_of)
      if (ours >= 0 && selected_.count(static_cast<std::uint32_t>(ours))) mine.insert(theirs);
    if (mine.empty()) mine.insert(UINT32_MAX - 1);  // none of this file's channels
    s.reader->select(mine);
  }
}

void Rosbag2Reader::close_slot(std::size_t i) {
  Slot& s = slots_[i];
  for (const std::string& note : s.reader->notes()) notes_.push_back(note);
  s.reader.reset();
  s.done = true;
  finished_bytes_ += s.size;
  if (!s.copy.empty()) {
    std::error_code ec;
    copy_bytes_open_ -= std::min(copy_bytes_open_, std::filesystem::file_size(s.copy, ec));
    std::filesystem::remove(s.copy, ec);
    --copies_open_;
  }
}

bool Rosbag2Reader::advance(std::size_t i) {
  Slot& s = slots_[i];
  while (s.reader->next(s.current)) {
    const auto ours = s.channel_of.find(s.current.channel->id);
    if (ours == s.channel_of.end() || ours->second < 0) {
      ++unlisted_[s.current.channel->topic];
      continue;
    }
    if (!selected_.empty() && !selected_.count(static_cast<std::uint32_t>(ours->second))) continue;
    return true;
  }
  close_slot(i);
  return false;
}

// Heap order: earliest timestamp on top, equal times in file order.
bool Rosbag2Reader::later(std::size_t a, std::size_t b) const {
  const auto ta = slots_[a].current.log_time_ns, tb = slots_[b].current.log_time_ns;
  return ta != tb ? ta > tb : a > b;
}

void Rosbag2Reader::push(std::size_t i) {
  heap_.push_back(i);
  std::push_heap(heap_.begin(), heap_.end(), [this](std::size_t a, std::size_t b) { return later(a, b); });
}

bool Rosbag2Reader::next(Message& out) {
  while (true) {
    if (last_) {  // the message handed out last is no longer needed
      if (advance(*last_)) push(*last_);
      last_.reset();
    }
    while (next_slot_ < slots_.size() &&
           (heap_.empty() || start_of(next_slot_) <= slots_[heap_.front()].current.log_time_ns)) {
      const std::size_t i = next_slot_++;
      if (!slots_[i].open) open_slot(i);
      if (advance(i)) push(i);
    }
    if (heap_.empty()) return false;
    std::pop_heap(heap_.begin(), heap_.end(), [this](std::size_t a, std::size_t b) { return later(a, b); });
    const std::size_t i = heap_.back();
    heap_.pop_back();
    last_ = i;
    const Message& m = slots_[i].current;
    const int ours = slots_[i].channel_of.at(m.channel->id);
    if (!selected_.empty() && !selected_.count(static_cast<std::uint32_t>(ours))) continue;  // deselected since
    out.channel = &channels_[static_cast<std::size_t>(ours)];
    out.log_time_ns = m.log_time_ns;
    out.data = m.data;
    out.index = delivered_++;
    // MESSAGE compression: said by metadata.yaml, or (a lone .db3) seen in the data: a CDR message
    // starts with 00, a zstd frame with 28 B5 2F FD.
    if (compression_mode_ == "MESSAGE" ||
        (!folder_ && out.channel->serialization == Serialization::kCdr && is_zstd_frame(out.data))) {
      const std::string where = fmt::format("ROS 2 bag {}: message {} (topic {}, {} ns)", path_, out.index,
                                            out.channel->topic, out.log_time_ns);
      const std::uint64_t bound =
          std::min<std::uint64_t>(out.data.size() * kMaxZstdRatio + (1u << 20), std::uint64_t{1} << 32);
      decompressor_.zstd_any(out.data, message_, bound, where);
      out.data = message_.span();
      ++zstd_messages_;
    }
    return true;
  }
}

void Rosbag2Reader::select(const std::set<std::uint32_t>& channel_ids) {
  selected_.clear();
  for (const std::uint32_t id : channel_ids)
    if (id < channels_.size()) selected_.insert(id);
  if (!channel_ids.empty() && selected_.empty()) selected_.insert(UINT32_MAX);
  for (Slot& s : slots_) {
    if (!s.open || s.done) continue;
    std::set<std::uint32_t> mine;
    if (!selected_.empty()) {
      for (const auto& [theirs, ours] : s.channel_of)
        if (ours >= 0 && selected_.count(static_cast<std::uint32_t>(ours))) mine.insert(theirs);
      if (mine.empty()) mine.insert(UINT32_MAX - 1);
    }
    s.reader->select(mine);
  }
}

std::uint64_t Rosbag2Reader::bytes_read() const {
  std::uint64_t n = finished_bytes_;
  for (const Slot& s : slots_)
    if (s.open && !s.done && s.copy.empty()) n += s.reader->bytes_read();
  return n;
}

std::string Rosbag2Reader::describe() const {
  const std::string compression =
      compression_mode_.empty() ? std::string() : fmt::format(", zstd {} compression", compression_mode_);
  if (!folder_) return "ROS 2 bag (a single sqlite3 .db3 file, without its metadata.yaml)";
  return fmt::format("ROS 2 bag ({} storage, {} file{}{})", storage_, slots_.size(), slots_.size() == 1 ? "" : "s",
                     compression);
}

std::vector<std::string> Rosbag2Reader::notes() const {
  std::vector<std::string> out = notes_;
  for (const Slot& s : slots_)
    if (s.open && !s.done)
      for (const std::string& note : s.reader->notes()) out.push_back(note);
  if (max_copies_open_ > 0)
    out.push_back(fmt::format("ROS 2 bag {}: its files are zstd-compressed whole (FILE mode): each was decompressed to a "
                              "temporary copy in {} while read (at most {} at once, {:.1f} MB)",
                              path_, temp_dir_, max_copies_open_, max_copy_bytes_ / 1e6));
  if (!folder_ && zstd_messages_ > 0)
    out.push_back(fmt::format("ROS 2 bag file {}: {} messages were zstd frames (message compression; no metadata.yaml "
                              "said so): decompressed",
                              path_, zstd_messages_));
  for (const auto& [topic, count] : unlisted_)
    out.push_back(fmt::format("ROS 2 bag {}: {} messages on topic {}, which metadata.yaml does not list, were skipped",
                              path_, count, topic));
  return out;
}

}  // namespace rosbag2_cpp

std::unique_ptr<RecordingReader> open_rosbag2(const std::filesystem::path& path) {
  return std::make_unique<rosbag2_cpp::Rosbag2Reader>(path);
}

}  // namespace slamvdb::recording
