// Header, CameraInfo, TF (both ROS 1 type names), Odometry, PoseStamped and TransformStamped
// decoding, on messages written by independent encoders in ROS 1 and CDR (little- and big-endian).
#include "slamvdb/recording/messages.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <map>

#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/ros_message_encoder.hpp"

namespace slamvdb::recording {
namespace messages_test {

using nlohmann::json;
using testing::EncodedMessage;
using testing::error_of;

json stamp(std::int64_t sec, std::int64_t nsec) { return {{"sec", sec}, {"nsec", nsec}}; }
json header(const std::string& frame, std::int64_t sec = 1700000000, std::int64_t nsec = 250000000) {
  return {{"seq", 42}, {"stamp", stamp(sec, nsec)}, {"frame_id", frame}};
}
json vec3(double x, double y, double z) { return {{"x", x}, {"y", y}, {"z", z}}; }
json quat(double x, double y, double z, double w) { return {{"x", x}, {"y", y}, {"z", z}, {"w", w}}; }
json transform_json(const std::string& parent, const std::string& child, const json& t, const json& q) {
  return {{"header", header(parent)}, {"child_frame_id", child}, {"transform", {{"translation", t}, {"rotation", q}}}};
}

std::vector<double> sequence(int n, double start) {
  std::vector<double> v;
  for (int i = 0; i < n; ++i) v.push_back(start + 0.5 * i);
  return v;
}

json messages_spec() {
  json m = json::array();
  m.push_back({{"name", "header"}, {"type", "std_msgs/Header"}, {"message", header("base_link", 12, 34)}});
  m.push_back({{"name", "camera_info"},
               {"type", "sensor_msgs/CameraInfo"},
               {"message",
                {{"header", header("pylon_camera")},
                 {"height", 400},
                 {"width", 640},
                 {"distortion_model", "plumb_bob"},
                 {"D", sequence(5, -0.25)},
                 {"K", sequence(9, 1.0)},
                 {"R", sequence(9, 10.0)},
                 {"P", sequence(12, 20.0)},
                 {"binning_x", 1},
                 {"binning_y", 2},
                 {"roi", {{"x_offset", 3}, {"y_offset", 4}, {"height", 5}, {"width", 6}, {"do_rectify", true}}}}}});
  m.push_back({{"name", "camera_info_fisheye"},
               {"type", "sensor_msgs/CameraInfo"},
               {"message",
                {{"header", header("fisheye")},
                 {"height", 1},
                 {"width", 2},
                 {"distortion_model", "equidistant"},
                 {"D", sequence(4, 0.5)},
                 {"K", sequence(9, 0.0)},
                 {"R", sequence(9, 0.0)},
                 {"P", sequence(12, 0.0)},
                 {"binning_x", 0},
                 {"binning_y", 0},
                 {"roi", {{"x_offset", 0}, {"y_offset", 0}, {"height", 0}, {"width", 0}, {"do_rectify", false}}}}}});
  const json transforms = {transform_json("os1_sensor", "pylon_camera", vec3(-0.13, 0.04, -0.17), quat(-0.5, 0.5, -0.5, 0.5)),
                           transform_json("map", "os1_sensor", vec3(10, 20, 30), quat(0, 0, 0, 2))};  // not normalised
  m.push_back({{"name", "tf2"}, {"type", "tf2_msgs/TFMessage"}, {"message", {{"transforms", transforms}}}});
  m.push_back({{"name", "tf1"}, {"type", "tf/tfMessage"}, {"message", {{"transforms", transforms}}}});
  m.push_back({{"name", "tf_empty"}, {"type", "tf2_msgs/TFMessage"}, {"message", {{"transforms", json::array()}}}});
  m.push_back({{"name", "tf_zero_rotation"},
               {"type", "tf2_msgs/TFMessage"},
               {"message", {{"transforms", {transform_json("a", "b", vec3(1, 2, 3), quat(0, 0, 0, 0))}}}}});
  m.push_back({{"name", "transform_stamped"},
               {"type", "geometry_msgs/TransformStamped"},
               {"message", transform_json("odom", "base_link", vec3(1, -2, 3), quat(0, 0, 0.6, 0.8))}});
  m.push_back({{"name", "odometry"},
               {"type", "nav_msgs/Odometry"},
               {"message",
                {{"header", header("map")},
                 {"child_frame_id", "os1_sensor"},
                 {"pose", {{"pose", {{"position", vec3(4, 5, 6)}, {"orientation", quat(0.6, 0, 0, 0.8)}}},
                           {"covariance", sequence(36, 0.0)}}},
                 {"twist", {{"twist", {{"linear", vec3(1.5, 0, 0)}, {"angular", vec3(0, 0, 0.25)}}},
                            {"covariance", sequence(36, 100.0)}}}}}});
  m.push_back({{"name", "pose_stamped"},
               {"type", "geometry_msgs/PoseStamped"},
               {"message", {{"header", header("map")}, {"pose", {{"position", vec3(7, 8, 9)}, {"orientation", quat(0, 0.8, 0, 0.6)}}}}}});
  return {{"messages", m}};
}

class MessageDecoding : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    encoded_ = new std::map<std::string, EncodedMessage>();
    const auto work = std::filesystem::temp_directory_path() / ("slamvdb-messages-" + std::to_string(::getpid()));
    testing::encode_ros_messages(messages_spec(), work, *encoded_);
    std::filesystem::remove_all(work);
  }
  static void TearDownTestSuite() { delete encoded_; }
  static const EncodedMessage& encoded(const std::string& name) { return encoded_->at(name); }
  static std::map<std::string, EncodedMessage>* encoded_;
};
std::map<std::string, EncodedMessage>* MessageDecoding::encoded_ = nullptr;

void expect_pose(const Pose& T, const Vec3d& t, const Eigen::Quaterniond& q) {
  EXPECT_TRUE(T.translation().isApprox(t, 1e-12)) << T.translation().transpose();
  EXPECT_TRUE(T.linear().isApprox(q.normalized().toRotationMatrix(), 1e-12)) << T.linear();
}

TEST_F(MessageDecoding, Header) {
  ASSERT_FALSE(HasFatalFailure());
  for (const auto& form : testing::forms_of(encoded("header"))) {
    const Header h = decode_header(*form.bytes, form.serialization);
    EXPECT_EQ(h.seq, form.serialization == Serialization::kRos1 ? 42u : 0u) << form.form;  // ROS 2 has no seq
    EXPECT_EQ(h.stamp_ns, 12'000000034) << form.form;
    EXPECT_DOUBLE_EQ(h.stamp_seconds(), 12.000000034);
    EXPECT_EQ(h.frame_id, "base_link");
  }
}

TEST_F(MessageDecoding, CameraInfo) {
  for (const auto& form : testing::forms_of(encoded("camera_info"))) {
    SCOPED_TRACE(form.form);
    const CameraInfo info = decode_camera_info(*form.bytes, form.serialization);
    EXPECT_EQ(info.header.frame_id, "pylon_camera");
    EXPECT_EQ(info.width, 640u);
    EXPECT_EQ(info.height, 400u);
    EXPECT_EQ(info.distortion_model, "plumb_bob");
    EXPECT_EQ(info.D, sequence(5, -0.25));
    EXPECT_EQ(std::vector<double>(info.K.begin(), info.K.end()), sequence(9, 1.0));
    EXPECT_EQ(std::vector<double>(info.R.begin(), info.R.end()), sequence(9, 10.0));
    EXPECT_EQ(std::vector<double>(info.P.begin(), info.P.end()), sequence(12, 20.0));
    EXPECT_EQ(info.binning_x, 1u);
    EXPECT_EQ(info.binning_y, 2u);
    EXPECT_EQ(info.roi_x_offset, 3u);
    EXPECT_EQ(info.roi_y_offset, 4u);
    EXPECT_EQ(info.roi_height, 5u);
    EXPECT_EQ(info.roi_width, 6u);
    EXPECT_TRUE(info.roi_do_rectify);
  }
  // Other models decode; the caller names the model when it refuses it.
  for (const auto& form : testing::forms_of(encoded("camera_info_fisheye"))) {
    const CameraInfo info = decode_camera_info(*form.bytes, form.serialization);
    EXPECT_EQ(info.distortion_model, "equidistant");
    EXPECT_EQ(info.D, sequence(4, 0.5));
  }
}

TEST_F(MessageDecoding, TfUnderBothTypeNames) {
  EXPECT_EQ(message_kind("tf2_msgs/TFMessage"), MessageKind::kTf);
  EXPECT_EQ(message_kind("tf/tfMessage"), MessageKind::kTf);
  EXPECT_EQ(message_kind("sensor_msgs/PointCloud2"), MessageKind::kPointCloud2);
  EXPECT_EQ(message_kind("sensor_msgs/msg/PointCloud2"), MessageKind::kUnknown) << "types arrive normalised";
  EXPECT_EQ(message_kind("sensor_msgs/Imu"), MessageKind::kUnknown);
  for (const std::string name : {"tf2", "tf1"}) {
    for (const auto& form : testing::forms_of(encoded(name))) {
      SCOPED_TRACE(name + " " + form.form);
      const std::vector<TransformStamped> tf = decode_tf_message(*form.bytes, form.serialization);
      ASSERT_EQ(tf.size(), 2u);
      EXPECT_EQ(tf[0].header.frame_id, "os1_sensor");
      EXPECT_EQ(tf[0].child_frame_id, "pylon_camera");
      EXPECT_EQ(tf[0].header.stamp_ns, 1700000000'250000000);
      expect_pose(tf[0].T_parent_child, Vec3d(-0.13, 0.04, -0.17), Eigen::Quaterniond(0.5, -0.5, 0.5, -0.5));
      EXPECT_EQ(tf[1].header.frame_id, "map");
      expect_pose(tf[1].T_parent_child, Vec3d(10, 20, 30), Eigen::Quaterniond::Identity());  // (0 0 0 2) normalised
    }
  }
  for (const auto& form : testing::forms_of(encoded("tf_empty")))
    EXPECT_TRUE(decode_tf_message(*form.bytes, form.serialization).empty());
  for (const auto& form : testing::forms_of(encoded("tf_zero_rotation"))) {
    const std::string e = error_of([&] { decode_tf_message(*form.bytes, form.serialization); });
    EXPECT_NE(e.find("tf2_msgs/TFMessage"), std::string::npos) << e;
    EXPECT_NE(e.find("field transforms[0].transform.rotation.w at byte"), std::string::npos) << e;
    EXPECT_NE(e.find("is not a rotation"), std::string::npos) << e;
  }
}

TEST_F(MessageDecoding, PosesFromOdometryPoseStampedAndTransformStamped) {
  for (const auto& form : testing::forms_of(encoded("odometry"))) {
    SCOPED_TRACE(form.form);
    const Odometry odometry = decode_odometry(*form.bytes, form.serialization);
    EXPECT_EQ(odometry.header.frame_id, "map");
    EXPECT_EQ(odometry.child_frame_id, "os1_sensor");
    expect_pose(odometry.T_frame_child, Vec3d(4, 5, 6), Eigen::Quaterniond(0.8, 0.6, 0, 0));
    EXPECT_EQ(odometry.pose_covariance[35], 17.5);
    EXPECT_EQ(odometry.linear_velocity, Vec3d(1.5, 0, 0));
    EXPECT_EQ(odometry.angular_velocity, Vec3d(0, 0, 0.25));
    EXPECT_EQ(odometry.twist_covariance[0], 100.0);
    EXPECT_EQ(odometry.twist_covariance[35], 117.5);
  }
  for (const auto& form : testing::forms_of(encoded("pose_stamped"))) {
    const PoseStamped pose = decode_pose_stamped(*form.bytes, form.serialization);
    EXPECT_EQ(pose.header.frame_id, "map");
    expect_pose(pose.T_frame_pose, Vec3d(7, 8, 9), Eigen::Quaterniond(0.6, 0, 0.8, 0));
  }
  for (const auto& form : testing::forms_of(encoded("transform_stamped"))) {
    const TransformStamped t = decode_transform_stamped(*form.bytes, form.serialization);
    EXPECT_EQ(t.header.frame_id, "odom");
    EXPECT_EQ(t.child_frame_id, "base_link");
    expect_pose(t.T_parent_child, Vec3d(1, -2, 3), Eigen::Quaterniond(0.8, 0, 0, 0.6));
  }
}

// Every message cut anywhere is an Error naming its type and a field, never a crash (the
// sanitizer builds run this too).
TEST_F(MessageDecoding, EveryTruncationIsAnErrorNamingTheField) {
  const std::map<std::string, std::function<void(std::span<const std::uint8_t>, Serialization)>> decoders = {
      {"header", [](auto b, auto s) { decode_header(b, s); }},
      {"camera_info", [](auto b, auto s) { decode_camera_info(b, s); }},
      {"tf2", [](auto b, auto s) { decode_tf_message(b, s); }},
      {"transform_stamped", [](auto b, auto s) { decode_transform_stamped(b, s); }},
      {"odometry", [](auto b, auto s) { decode_odometry(b, s); }},
      {"pose_stamped", [](auto b, auto s) { decode_pose_stamped(b, s); }}};
  for (const auto& [name, decode] : decoders) {
    for (const auto& form : testing::forms_of(encoded(name))) {
      const auto& full = *form.bytes;
      for (std::size_t size = 0; size < full.size(); ++size) {
        const std::vector<std::uint8_t> cut(full.begin(), full.begin() + size);
        const std::string e = error_of([&] { decode(cut, form.serialization); });
        ASSERT_NE(e.find(": field "), std::string::npos) << name << " " << form.form << " cut to " << size << ": " << e;
      }
      // And bytes left over mean another type: an Error too.
      std::vector<std::uint8_t> longer = full;
      longer.resize(full.size() + 8, 0);
      EXPECT_NE(error_of([&] { decode(longer, form.serialization); }).find("bytes are left after the last field"),
                std::string::npos)
          << name << " " << form.form;
    }
  }
}

TEST_F(MessageDecoding, AbsurdCountsAreErrorsBeforeAllocating) {
  std::vector<std::uint8_t> tf = encoded("tf2").ros1;  // the count is the first field
  tf[0] = tf[1] = tf[2] = 0xff;
  tf[3] = 0x7f;
  const std::string e = error_of([&] { decode_tf_message(tf, Serialization::kRos1); });
  EXPECT_NE(e.find("field transforms at byte 0: a sequence of 2147483647 elements"), std::string::npos) << e;
  std::vector<std::uint8_t> be = encoded("tf2").cdr_be;  // after the 4-byte encapsulation header
  be[4] = 0x10;
  const std::string e2 = error_of([&] { decode_tf_message(be, Serialization::kCdr); });
  EXPECT_NE(e2.find("CDR big-endian): field transforms at byte 4: a sequence of 268435458 elements"), std::string::npos)
      << e2;
}

}  // namespace messages_test
}  // namespace slamvdb::recording
