// Seeds of the ROS harnesses (ros1_bag, ros_messages): small messages in ROS 1 serialization and
// CDR (little- and big-endian) and small bags with uncompressed, lz4 and bz2 chunks, with and
// without index. Written here by a minimal serializer: the tests check the decoders against
// independent encoders; seeds only need to reach deep into the readers.
#include <bzlib.h>
#include <lz4frame.h>

#include <cstdint>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

namespace {

// ROS 1 (packed little-endian) or CDR (4-byte header, alignment from its end).
struct Writer {
  enum Form { kRos1, kCdrLe, kCdrBe } form;
  std::string out;
  explicit Writer(Form f) : form(f) {
    if (form != kRos1) out = std::string("\0", 1) + (form == kCdrLe ? '\1' : '\0') + std::string(2, '\0');
  }
  void align(std::size_t n) {
    if (form != kRos1)
      while ((out.size() - 4) % n) out.push_back('\0');
  }
  template <typename T>
  Writer& put(T v) {
    align(sizeof(T));
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (form == kCdrBe)
      for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    out.append(b, sizeof(T));
    return *this;
  }
  Writer& str(const std::string& s) {
    put<std::uint32_t>(static_cast<std::uint32_t>(s.size() + (form == kRos1 ? 0 : 1)));
    out += s;
    if (form != kRos1) out.push_back('\0');
    return *this;
  }
  Writer& header(const std::string& frame) {
    if (form == kRos1) put<std::uint32_t>(1);
    put<std::uint32_t>(1700000000).put<std::uint32_t>(5000);
    return str(frame);
  }
  Writer& bytes(const std::string& b) {
    put<std::uint32_t>(static_cast<std::uint32_t>(b.size()));
    out += b;
    return *this;
  }
  Writer& pose() {
    for (double v : {1.0, 2.0, 3.0, 0.0, 0.0, 0.0, 1.0}) put(v);
    return *this;
  }
};

std::string cloud(Writer w) {
  w.header("os1_sensor").put<std::uint32_t>(1).put<std::uint32_t>(2).put<std::uint32_t>(5);
  const char* names[] = {"x", "y", "z", "intensity", "t"};
  for (int i = 0; i < 5; ++i)
    w.str(names[i]).put<std::uint32_t>(4 * i).put<std::uint8_t>(i == 4 ? 6 : 7).put<std::uint32_t>(1);
  std::string data;
  for (float v : {1.0f, 2.0f, 3.0f, 0.5f, 0.0f, 4.0f, 5.0f, 6.0f, 0.5f, 0.0f}) data.append(reinterpret_cast<char*>(&v), 4);
  w.put<std::uint8_t>(0).put<std::uint32_t>(20).put<std::uint32_t>(40).bytes(data).put<std::uint8_t>(1);
  return w.out;
}

std::string image(Writer w) {
  w.header("cam").put<std::uint32_t>(2).put<std::uint32_t>(2).str("rgb8").put<std::uint8_t>(0).put<std::uint32_t>(8);
  return w.bytes(std::string("\1\2\3\4\5\6\0\0\7\10\11\12\13\14\0\0", 16)).out;
}

std::string camera_info(Writer w) {
  w.header("cam").put<std::uint32_t>(400).put<std::uint32_t>(640).str("plumb_bob").put<std::uint32_t>(5);
  for (int i = 0; i < 5 + 9 + 9 + 12; ++i) w.put(0.5 * i);
  w.put<std::uint32_t>(0).put<std::uint32_t>(0);
  for (int i = 0; i < 4; ++i) w.put<std::uint32_t>(0);
  return w.put<std::uint8_t>(0).out;
}

std::string transform(Writer& w) { return w.header("map").str("os1_sensor").pose().out; }

}  // namespace

namespace {

// A record: header fields, data.
std::string record(const std::vector<std::pair<std::string, std::string>>& fields, const std::string& data) {
  std::string header;
  for (const auto& [name, value] : fields) {
    const std::uint32_t n = static_cast<std::uint32_t>(name.size() + 1 + value.size());
    header.append(reinterpret_cast<const char*>(&n), 4).append(name).append("=").append(value);
  }
  std::string out;
  const std::uint32_t h = static_cast<std::uint32_t>(header.size()), d = static_cast<std::uint32_t>(data.size());
  return out.append(reinterpret_cast<const char*>(&h), 4).append(header).append(reinterpret_cast<const char*>(&d), 4) + data;
}
template <typename T>
std::string raw(T v) {
  return std::string(reinterpret_cast<const char*>(&v), sizeof(T));
}

std::string bag(const std::string& compression, bool indexed) {
  const std::string connection_fields =
      record({{"type", "geometry_msgs/PoseStamped"}, {"md5sum", "d3812c3cbc69362b77dc0b19b345f8f5"}}, "");
  const std::string connection_data = connection_fields.substr(4, connection_fields.size() - 8);  // the fields only
  const std::string connection = record({{"op", "\x07"}, {"conn", raw<std::uint32_t>(0)}, {"topic", "/pose"}},
                                        connection_data);
  std::string chunk_data = connection;
  for (std::uint32_t i = 0; i < 3; ++i) {
    Writer w(Writer::kRos1);
    w.header("map").pose();
    chunk_data += record({{"op", "\x02"}, {"conn", raw<std::uint32_t>(0)}, {"time", raw<std::uint32_t>(1700000000 + i) + raw<std::uint32_t>(0)}}, w.out);
  }
  std::string stored = chunk_data;
  if (compression == "lz4") {
    LZ4F_preferences_t prefs{};
    prefs.frameInfo.contentChecksumFlag = LZ4F_contentChecksumEnabled;
    stored.resize(LZ4F_compressFrameBound(chunk_data.size(), &prefs));
    stored.resize(LZ4F_compressFrame(stored.data(), stored.size(), chunk_data.data(), chunk_data.size(), &prefs));
  } else if (compression == "bz2") {
    unsigned n = static_cast<unsigned>(chunk_data.size() * 2 + 600);
    stored.resize(n);
    BZ2_bzBuffToBuffCompress(stored.data(), &n, chunk_data.data(), static_cast<unsigned>(chunk_data.size()), 1, 0, 0);
    stored.resize(n);
  }
  const std::string magic = "#ROSBAG V2.0\n";
  const std::uint64_t chunk_pos = magic.size() + 4096;
  const std::string chunk = record({{"op", "\x05"}, {"compression", compression}, {"size", raw<std::uint32_t>(static_cast<std::uint32_t>(chunk_data.size()))}}, stored);
  const std::string index_data = record({{"op", "\x04"}, {"ver", raw<std::uint32_t>(1)}, {"conn", raw<std::uint32_t>(0)}, {"count", raw<std::uint32_t>(0)}}, "");
  const std::uint64_t index_pos = indexed ? chunk_pos + chunk.size() + index_data.size() : 0;
  std::string header = record({{"op", "\x03"}, {"index_pos", raw(index_pos)}, {"conn_count", raw<std::uint32_t>(1)}, {"chunk_count", raw<std::uint32_t>(1)}}, "");
  const std::uint32_t padding = static_cast<std::uint32_t>(4096 - header.size());
  header.replace(header.size() - 4, 4, raw(padding));
  header.append(padding, ' ');
  std::string out = magic + header + chunk + index_data;
  if (indexed) {
    out += connection;
    out += record({{"op", "\x06"}, {"ver", raw<std::uint32_t>(1)}, {"chunk_pos", raw(chunk_pos)},
                   {"start_time", raw<std::uint32_t>(1700000000) + raw<std::uint32_t>(0)},
                   {"end_time", raw<std::uint32_t>(1700000002) + raw<std::uint32_t>(0)}, {"count", raw<std::uint32_t>(1)}},
                  raw<std::uint32_t>(0) + raw<std::uint32_t>(3));
  }
  return out;
}

}  // namespace

void write_ros_seeds(const std::function<void(const std::string&, const std::string&, const std::string&)>& seed) {
  for (const auto form : {Writer::kRos1, Writer::kCdrLe, Writer::kCdrBe}) {
    const std::string name = form == Writer::kRos1 ? "ros1" : form == Writer::kCdrLe ? "cdr_le" : "cdr_be";
    const char serialization = form == Writer::kRos1 ? 0 : 0x10;
    const auto message = [&](int decoder, const std::string& kind, const std::string& bytes) {
      seed("ros_messages", kind + "_" + name, std::string(1, static_cast<char>(serialization | decoder)) + bytes);
    };
    message(0, "point_cloud2", cloud(Writer(form)));
    message(1, "image", image(Writer(form)));
    message(2, "compressed_image", Writer(form).header("cam").str("jpeg").bytes("\xff\xd8\xff").out);
    message(3, "camera_info", camera_info(Writer(form)));
    Writer tf(form);
    tf.put<std::uint32_t>(2);
    transform(tf);
    message(4, "tf", transform(tf));
    Writer odometry(form);
    odometry.header("map").str("os1_sensor").pose();
    for (int i = 0; i < 36 + 6 + 36; ++i) odometry.put(0.0);
    message(5, "odometry", odometry.out);
    message(6, "pose_stamped", Writer(form).header("map").pose().out);
    Writer single(form);
    message(7, "transform_stamped", transform(single));
    message(8, "header", Writer(form).header("base_link").out);
  }
  for (const std::string compression : {"none", "lz4", "bz2"}) {
    seed("ros1_bag", compression + "_indexed", bag(compression, true));
    seed("ros1_bag", compression + "_unindexed", bag(compression, false));
  }
}
