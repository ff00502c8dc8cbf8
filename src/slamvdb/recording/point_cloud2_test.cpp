// PointCloud2 decoding and point extraction, on messages written by independent encoders (npm
// @foxglove/rosmsg-serialization for ROS 1, @foxglove/rosmsg2-serialization for CDR little- and
// big-endian) in every layout the issue names.
#include "slamvdb/recording/point_cloud2.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <map>

#include "slamvdb/core/error.hpp"
#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/ros_message_encoder.hpp"

namespace slamvdb::recording {
namespace point_cloud2_test {

using nlohmann::json;
using testing::EncodedMessage;
using testing::error_of;

constexpr std::int64_t kStampSec = 1700000000, kStampNsec = 500000000;

struct CloudCase {
  json spec;
  std::vector<Vec3f> points;  // expected (NaN where the message has NaN)
  std::vector<float> times;   // expected seconds relative to the stamp; empty: no time field
  PointTimeField time_field = PointTimeField::kNone;
  bool fast_path = false;
};

json field(const std::string& name, int offset, int datatype) {
  return {{"name", name}, {"offset", offset}, {"datatype", datatype}, {"count", 1}};
}

// A cloud message of `points` (each a JSON object of field values) in the given layout.
json cloud_spec(const std::string& name, const json& fields, int point_step, int height, int width, const json& points,
                bool big_endian = false, bool dense = true) {
  return {{"name", name},
          {"type", "sensor_msgs/PointCloud2"},
          {"message", {{"header", {{"seq", 3}, {"stamp", {{"sec", kStampSec}, {"nsec", kStampNsec}}}, {"frame_id", "os1_sensor"}}}}},
          {"cloud",
           {{"fields", fields}, {"height", height}, {"width", width}, {"point_step", point_step},
            {"is_bigendian", big_endian}, {"is_dense", dense}, {"points", points}}}};
}

std::map<std::string, CloudCase> make_cases() {
  std::map<std::string, CloudCase> cases;
  const auto xyz_values = [](int i) { return Vec3f(0.5f * i - 3.0f, 2.0f * i, 100.0f + i); };
  {  // The common layout (float32 x y z intensity, uint32 t), unorganised: the fast path.
    CloudCase c;
    json points = json::array();
    for (int i = 0; i < 7; ++i) {
      const Vec3f p = xyz_values(i);
      points.push_back({{"x", p.x()}, {"y", p.y()}, {"z", p.z()}, {"intensity", 10 * i}, {"t", i * 1000000}});
      c.points.push_back(p);
      c.times.push_back(i * 1e-3f);
    }
    c.spec = cloud_spec("common",
                        {field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("intensity", 12, 7), field("t", 16, 6)},
                        20, 1, 7, points);
    c.time_field = PointTimeField::kT;
    c.fast_path = true;
    cases["common"] = c;
  }
  {  // Ouster's 48-byte points, organised 4 x 3: padding between and after the fields.
    CloudCase c;
    json points = json::array();
    for (int i = 0; i < 12; ++i) {
      const Vec3f p = xyz_values(i);
      points.push_back({{"x", p.x()}, {"y", p.y()}, {"z", p.z()}, {"intensity", 1.5}, {"t", 5000 * i},
                        {"reflectivity", 7}, {"ring", i / 3}, {"ambient", 9}, {"range", 12345}});
      c.points.push_back(p);
      c.times.push_back(5e-6f * i);
    }
    c.spec = cloud_spec("ouster48",
                        {field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("intensity", 16, 7), field("t", 20, 6),
                         field("reflectivity", 24, 4), field("ring", 26, 4), field("ambient", 28, 4), field("range", 32, 6)},
                        48, 4, 3, points);
    c.time_field = PointTimeField::kT;
    c.fast_path = true;
    cases["ouster48"] = c;
  }
  for (int datatype = 1; datatype <= 8; ++datatype) {  // x y z of every datatype, 3 bytes of padding
    const int size = static_cast<int>(point_field_type_size(static_cast<std::uint8_t>(datatype)));
    const bool is_signed = datatype == 1 || datatype == 3 || datatype == 5 || datatype >= 7;
    CloudCase c;
    json points = json::array();
    for (int i = 0; i < 5; ++i) {
      const Vec3f p(is_signed ? i - 3.0f : static_cast<float>(i), 2.0f * i, 100.0f + i);
      points.push_back({{"x", p.x()}, {"y", p.y()}, {"z", p.z()}});
      c.points.push_back(p);
    }
    const std::string name = "datatype" + std::to_string(datatype);
    c.spec = cloud_spec(name, {field("x", 0, datatype), field("y", size, datatype), field("z", 2 * size, datatype)},
                        3 * size + 3, 1, 5, points);
    c.fast_path = datatype == 7;
    cases[name] = c;
  }
  {  // Mixed datatypes, and `timestamp` (absolute float64 seconds, Hesai): times relative to the stamp.
    CloudCase c;
    json points = json::array();
    for (int i = 0; i < 6; ++i) {
      const Vec3f p(0.25f * i, static_cast<float>(-i), 1.5f * i);
      points.push_back({{"x", p.x()}, {"y", p.y()}, {"z", p.z()}, {"timestamp", kStampSec + 0.5 + 0.001 * i}});
      c.points.push_back(p);
      c.times.push_back(0.001f * i);
    }
    c.spec = cloud_spec("mixed", {field("x", 0, 8), field("y", 8, 3), field("z", 10, 7), field("timestamp", 14, 8)}, 24, 1,
                        6, points);
    c.time_field = PointTimeField::kTimestamp;
    cases["mixed"] = c;
  }
  {  // Big-endian float32, with Velodyne's `time` (float32 s relative, negative before the stamp).
    CloudCase c;
    json points = json::array();
    for (int i = 0; i < 5; ++i) {
      const Vec3f p = xyz_values(i);
      points.push_back({{"x", p.x()}, {"y", p.y()}, {"z", p.z()}, {"time", -0.0625 + 0.015625 * i}});
      c.points.push_back(p);
      c.times.push_back(static_cast<float>(-0.0625 + 0.015625 * i));
    }
    c.spec = cloud_spec("big_endian_f32",
                        {field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("time", 12, 7)}, 16, 1, 5, points,
                        true);
    c.time_field = PointTimeField::kTime;
    cases["big_endian_f32"] = c;
  }
  {  // Big-endian float64, with Livox's `offset_time` (uint32 ns).
    CloudCase c;
    json points = json::array();
    for (int i = 0; i < 4; ++i) {
      const Vec3f p = xyz_values(i);
      points.push_back({{"x", p.x()}, {"y", p.y()}, {"z", p.z()}, {"offset_time", 250000 * i}});
      c.points.push_back(p);
      c.times.push_back(2.5e-4f * i);
    }
    c.spec = cloud_spec("big_endian_f64",
                        {field("offset_time", 0, 6), field("x", 4, 8), field("y", 12, 8), field("z", 20, 8)}, 28, 2, 2,
                        points, true);
    c.time_field = PointTimeField::kOffsetTime;
    cases["big_endian_f64"] = c;
  }
  {  // Organised 3 x 2 with 8 bytes of padding at the end of each row (row_step 40 > 2 x 16).
    CloudCase c;
    json points = json::array();
    for (int i = 0; i < 6; ++i) {
      const Vec3f p = xyz_values(i);
      points.push_back({{"x", p.x()}, {"y", p.y()}, {"z", p.z()}, {"t", 1000 * i}});
      c.points.push_back(p);
      c.times.push_back(1e-6f * i);
    }
    c.spec = cloud_spec("row_padding", {field("x", 0, 7), field("y", 4, 7), field("z", 8, 7), field("t", 12, 6)}, 16, 3,
                        2, points);
    c.spec["cloud"]["row_step"] = 40;
    c.time_field = PointTimeField::kT;
    c.fast_path = true;
    cases["row_padding"] = c;
  }
  {  // Not dense: rays without a return are NaN, and stay NaN.
    CloudCase c;
    json points = json::array();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int i = 0; i < 6; ++i) {
      const bool missing = i % 2 == 1;
      const Vec3f p = missing ? Vec3f(nan, nan, nan) : xyz_values(i);
      points.push_back(missing ? json{{"x", "nan"}, {"y", "nan"}, {"z", "nan"}}
                               : json{{"x", p.x()}, {"y", p.y()}, {"z", p.z()}});
      c.points.push_back(p);
    }
    c.spec = cloud_spec("nan", {field("x", 0, 7), field("y", 4, 7), field("z", 8, 7)}, 12, 2, 3, points, false, false);
    c.fast_path = true;
    cases["nan"] = c;
  }
  {
    CloudCase c;
    c.spec = cloud_spec("empty", {field("x", 0, 7), field("y", 4, 7), field("z", 8, 7)}, 12, 1, 0, json::array());
    c.fast_path = true;
    cases["empty"] = c;
  }
  return cases;
}

class PointCloud2Decoding : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    cases_ = new std::map<std::string, CloudCase>(make_cases());
    json spec = {{"messages", json::array()}};
    for (const auto& [name, c] : *cases_) spec["messages"].push_back(c.spec);
    // Damaged layouts (the encoder writes what it is given).
    json bad = cloud_spec("bad_row_step", {field("x", 0, 7), field("y", 4, 7), field("z", 8, 7)}, 12, 2, 3,
                          json::array());
    bad["cloud"]["row_step"] = 32;  // < 3 x 12
    bad["cloud"]["data_size"] = 64;
    spec["messages"].push_back(bad);
    bad = cloud_spec("bad_data_size", {field("x", 0, 7), field("y", 4, 7), field("z", 8, 7)}, 12, 2, 3, json::array());
    bad["cloud"]["data_size"] = 60;  // < 2 x 36
    spec["messages"].push_back(bad);
    spec["messages"].push_back(cloud_spec("no_x", {field("y", 4, 7), field("z", 8, 7)}, 12, 1, 2, json::array()));
    spec["messages"].push_back(
        cloud_spec("field_past_step", {field("x", 0, 7), field("y", 4, 7), field("z", 10, 7)}, 12, 1, 2, json::array()));
    spec["messages"].push_back(
        cloud_spec("bad_datatype", {field("x", 0, 9), field("y", 4, 7), field("z", 8, 7)}, 12, 1, 2, json::array()));
    encoded_ = new std::map<std::string, EncodedMessage>();
    const auto work = std::filesystem::temp_directory_path() / ("slamvdb-pc2-" + std::to_string(::getpid()));
    testing::encode_ros_messages(spec, work, *encoded_);
    std::filesystem::remove_all(work);
  }
  static void TearDownTestSuite() {
    delete cases_;
    delete encoded_;
  }
  static const EncodedMessage& encoded(const std::string& name) {
    const auto it = encoded_->find(name);
    if (it == encoded_->end()) throw std::runtime_error("no encoded message " + name);
    return it->second;
  }
  static std::map<std::string, CloudCase>* cases_;
  static std::map<std::string, EncodedMessage>* encoded_;
};
std::map<std::string, CloudCase>* PointCloud2Decoding::cases_ = nullptr;
std::map<std::string, EncodedMessage>* PointCloud2Decoding::encoded_ = nullptr;

TEST_F(PointCloud2Decoding, EveryLayoutInEverySerialization) {
  ASSERT_FALSE(HasFatalFailure());
  std::vector<Vec3f> points = {Vec3f(9, 9, 9)};  // reused buffers: stale content must not leak through
  std::vector<float> times = {42.0f}, intensity;
  for (const auto& [name, c] : *cases_) {
    for (const auto& form : testing::forms_of(encoded(name))) {
      SCOPED_TRACE(name + " in " + form.form);
      const PointCloud2View cloud = decode_point_cloud2(*form.bytes, form.serialization);
      EXPECT_EQ(cloud.header.stamp_ns, kStampSec * 1'000'000'000 + kStampNsec);
      EXPECT_EQ(cloud.header.frame_id, "os1_sensor");
      EXPECT_EQ(cloud.header.seq, form.serialization == Serialization::kRos1 ? 3u : 0u);
      EXPECT_EQ(cloud.point_count(), c.points.size());
      const CloudExtraction result = extract_points(cloud, points, &times, &intensity);
      EXPECT_EQ(result.points, c.points.size());
      EXPECT_EQ(result.time_field, c.time_field);
      EXPECT_EQ(result.fast_path, c.fast_path);
      ASSERT_EQ(points.size(), c.points.size());
      for (std::size_t i = 0; i < points.size(); ++i) {
        for (int k = 0; k < 3; ++k) {
          if (std::isnan(c.points[i][k]))
            EXPECT_TRUE(std::isnan(points[i][k])) << "point " << i;
          else
            EXPECT_EQ(points[i][k], c.points[i][k]) << "point " << i << " axis " << k;
        }
      }
      ASSERT_EQ(times.size(), c.times.size());
      for (std::size_t i = 0; i < times.size(); ++i) EXPECT_NEAR(times[i], c.times[i], 2e-7) << "point " << i;
      if (name == "common") {
        ASSERT_EQ(intensity.size(), c.points.size());
        for (std::size_t i = 0; i < intensity.size(); ++i) EXPECT_EQ(intensity[i], 10.0f * i);
      }
    }
  }
}

TEST_F(PointCloud2Decoding, ViewDescribesTheMessage) {
  const PointCloud2View cloud = decode_point_cloud2(encoded("ouster48").cdr_be, Serialization::kCdr);
  EXPECT_EQ(cloud.height, 4u);
  EXPECT_EQ(cloud.width, 3u);
  EXPECT_EQ(cloud.point_step, 48u);
  EXPECT_EQ(cloud.row_step, 144u);
  EXPECT_EQ(cloud.data.size(), 4u * 144u);
  EXPECT_TRUE(cloud.is_dense);
  EXPECT_FALSE(cloud.is_bigendian);
  ASSERT_EQ(cloud.fields.size(), 9u);
  EXPECT_EQ(cloud.fields[8].name, "range");
  EXPECT_EQ(cloud.fields[8].offset, 32u);
  EXPECT_EQ(cloud.fields[8].datatype, 6);
  EXPECT_EQ(cloud.fields[8].count, 1u);
  std::vector<Vec3f> points;
  EXPECT_EQ(extract_points(cloud, points).time_field, PointTimeField::kNone) << "no times asked for";
}

TEST_F(PointCloud2Decoding, LayoutErrorsNameTheField) {
  for (const auto& form : testing::forms_of(encoded("bad_row_step"))) {
    const std::string e = error_of([&] { decode_point_cloud2(*form.bytes, form.serialization); });
    EXPECT_NE(e.find("sensor_msgs/PointCloud2"), std::string::npos) << e;
    EXPECT_NE(e.find("field row_step at byte"), std::string::npos) << e;
    EXPECT_NE(e.find("width 3 x point_step 12"), std::string::npos) << e;
  }
  for (const auto& form : testing::forms_of(encoded("bad_data_size"))) {
    const std::string e = error_of([&] { decode_point_cloud2(*form.bytes, form.serialization); });
    EXPECT_NE(e.find("field data at byte"), std::string::npos) << e;
    EXPECT_NE(e.find("has 60 bytes"), std::string::npos) << e;
  }
  std::vector<Vec3f> points;
  const auto extract_error = [&](const std::string& name) {
    return error_of([&] { extract_points(decode_point_cloud2(encoded(name).ros1, Serialization::kRos1), points); });
  };
  EXPECT_NE(extract_error("no_x").find("has no field x (its fields: y, z)"), std::string::npos) << extract_error("no_x");
  EXPECT_NE(extract_error("field_past_step").find("field z (4 bytes at offset 10) does not fit in point_step 12"),
            std::string::npos)
      << extract_error("field_past_step");
  EXPECT_NE(extract_error("bad_datatype").find("field x has datatype 9"), std::string::npos)
      << extract_error("bad_datatype");
}

TEST_F(PointCloud2Decoding, EveryTruncationIsAnErrorNamingAField) {
  for (const std::string name : {"common", "mixed", "row_padding"}) {
    for (const auto& form : testing::forms_of(encoded(name))) {
      const std::vector<std::uint8_t>& full = *form.bytes;
      for (std::size_t size = 0; size < full.size(); ++size) {
        const std::vector<std::uint8_t> cut(full.begin(), full.begin() + size);
        const std::string e = error_of([&] { decode_point_cloud2(cut, form.serialization); });
        ASSERT_NE(e.find("sensor_msgs/PointCloud2"), std::string::npos)
            << name << " " << form.form << " cut to " << size << " bytes decoded: " << e;
        ASSERT_NE(e.find("field "), std::string::npos) << e;
      }
    }
  }
}

TEST_F(PointCloud2Decoding, AbsurdCountsAreErrorsBeforeAllocating) {
  // The fields count follows header (seq, stamp, frame_id "os1_sensor"), height and width.
  std::vector<std::uint8_t> ros1 = encoded("common").ros1;
  const std::size_t at = 4 + 8 + 4 + 10 + 4 + 4;
  ASSERT_EQ(ros1[at], 5);  // five fields
  ros1[at] = ros1[at + 1] = ros1[at + 2] = ros1[at + 3] = 0xff;
  const std::string e = error_of([&] { decode_point_cloud2(ros1, Serialization::kRos1); });
  EXPECT_NE(e.find("field fields at byte " + std::to_string(at)), std::string::npos) << e;
  EXPECT_NE(e.find("4294967295 elements"), std::string::npos) << e;
  // The data length of a big-endian CDR message.
  std::vector<std::uint8_t> be = encoded("common").cdr_be;
  const std::size_t data_at = be.size() - 1 - 7 * 20 - 4;  // is_dense last, 7 points of 20 bytes before it
  ASSERT_EQ(be[data_at + 3], 140);
  be[data_at] = 0x7f;
  const std::string e2 = error_of([&] { decode_point_cloud2(be, Serialization::kCdr); });
  EXPECT_NE(e2.find("CDR big-endian): field data at byte " + std::to_string(data_at + 4)), std::string::npos) << e2;
}

TEST_F(PointCloud2Decoding, EncapsulationsOtherThanPlainCdrAreErrors) {
  std::vector<std::uint8_t> bytes = encoded("common").cdr_le;
  bytes[1] = 0x03;  // PL_CDR_LE
  EXPECT_NE(error_of([&] { decode_point_cloud2(bytes, Serialization::kCdr); }).find("parameter-list"), std::string::npos);
  bytes[1] = 0x42;
  EXPECT_NE(error_of([&] { decode_point_cloud2(bytes, Serialization::kCdr); }).find("unknown encapsulation kind 0x42"),
            std::string::npos);
}

}  // namespace point_cloud2_test
}  // namespace slamvdb::recording
