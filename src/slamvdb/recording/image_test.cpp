// sensor_msgs/Image and CompressedImage decoding, on messages written by independent encoders in
// ROS 1 and CDR (little- and big-endian): every encoding slamvdb reads, with row padding.
#include "slamvdb/recording/image.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <map>

#include "slamvdb/testing/error_of.hpp"
#include "slamvdb/testing/ros_message_encoder.hpp"

namespace slamvdb::recording {
namespace image_test {

using nlohmann::json;
using testing::EncodedMessage;
using testing::error_of;

constexpr int kWidth = 3, kHeight = 2;

int channels_of(const std::string& encoding) {
  if (encoding == "rgb8" || encoding == "bgr8") return 3;
  if (encoding == "rgba8" || encoding == "bgra8") return 4;
  return 1;
}

// Channel k of pixel i (distinct values, so that a swapped or shifted channel shows).
int channel_value(int i, int k, bool wide) { return wide ? 1000 * i + 300 + k : (i * 40 + k * 7 + 1) & 255; }

json image_spec(const std::string& name, const std::string& encoding, int step, bool big_endian = false,
                bool wide = false, int label_scale = 0) {
  const int channels = channels_of(encoding);
  json pixels = json::array();
  for (int i = 0; i < kWidth * kHeight; ++i) {
    json p = json::array();
    for (int k = 0; k < channels; ++k) p.push_back(label_scale ? label_scale * i : channel_value(i, k, wide));
    pixels.push_back(p);
  }
  return {{"name", name},
          {"type", "sensor_msgs/Image"},
          {"message", {{"header", {{"seq", 1}, {"stamp", {{"sec", 1700000001}, {"nsec", 7}}}, {"frame_id", "cam"}}}}},
          {"image",
           {{"encoding", encoding}, {"width", kWidth}, {"height", kHeight}, {"step", step}, {"is_bigendian", big_endian},
            {"bytes_per_channel", encoding == "mono16" || encoding == "16UC1" ? 2 : 1}, {"pixels", pixels}}}};
}

class ImageDecoding : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    json spec = {{"messages", json::array()}};
    // Each with 2 bytes of row padding.
    for (const std::string e : {"rgb8", "bgr8", "rgba8", "bgra8", "mono8", "8UC1"})
      spec["messages"].push_back(image_spec(e, e, kWidth * channels_of(e) + 2));
    spec["messages"].push_back(image_spec("mono16_le", "mono16", 8, false, true));
    spec["messages"].push_back(image_spec("mono16_be", "mono16", 8, true, true));
    spec["messages"].push_back(image_spec("labels16", "16UC1", 8, true, false, 50));
    spec["messages"].push_back(image_spec("bad_step", "rgb8", 8));
    json short_data = image_spec("short_data", "mono8", 4);
    short_data["image"]["data_size"] = 6;
    spec["messages"].push_back(short_data);
    spec["messages"].push_back(image_spec("bayer", "bayer_rggb8", 3));
    json empty = image_spec("empty", "mono8", 0);  // 0 x 2: found by the fuzzer (a memcpy from no data)
    empty["image"]["width"] = 0;
    empty["image"]["pixels"] = json::array();
    spec["messages"].push_back(empty);
    spec["messages"].push_back({{"name", "compressed"},
                                {"type", "sensor_msgs/CompressedImage"},
                                {"message",
                                 {{"header", {{"stamp", {{"sec", 5}, {"nsec", 6}}}, {"frame_id", "pylon_camera"}}},
                                  {"format", "jpeg"},
                                  {"data", {0xff, 0xd8, 0xff, 0xe0, 1, 2, 3}}}}});
    encoded_ = new std::map<std::string, EncodedMessage>();
    const auto work = std::filesystem::temp_directory_path() / ("slamvdb-image-" + std::to_string(::getpid()));
    testing::encode_ros_messages(spec, work, *encoded_);
    std::filesystem::remove_all(work);
  }
  static void TearDownTestSuite() { delete encoded_; }
  static const EncodedMessage& encoded(const std::string& name) { return encoded_->at(name); }
  static std::map<std::string, EncodedMessage>* encoded_;
};
std::map<std::string, EncodedMessage>* ImageDecoding::encoded_ = nullptr;

TEST_F(ImageDecoding, EveryEncodingWithRowPaddingToRgb) {
  ASSERT_FALSE(HasFatalFailure());
  std::vector<std::uint8_t> rgb(1000, 7);  // reused: resized to the image
  for (const std::string name : {"rgb8", "bgr8", "rgba8", "bgra8", "mono8", "8UC1", "mono16_le", "mono16_be"}) {
    for (const auto& form : testing::forms_of(encoded(name))) {
      SCOPED_TRACE(name + " in " + form.form);
      const ImageView image = decode_image(*form.bytes, form.serialization);
      EXPECT_EQ(image.header.stamp_ns, 1700000001'000000007);
      EXPECT_EQ(image.header.frame_id, "cam");
      EXPECT_EQ(image.width, 3u);
      EXPECT_EQ(image.height, 2u);
      image_to_rgb8(image, rgb);
      ASSERT_EQ(rgb.size(), 3u * kWidth * kHeight);
      const bool wide = name.starts_with("mono16");
      const bool bgr = name.starts_with("bgr");
      const bool mono = channels_of(image.encoding) == 1;
      for (int i = 0; i < kWidth * kHeight; ++i) {
        for (int k = 0; k < 3; ++k) {
          const int source = mono ? 0 : bgr ? 2 - k : k;
          const int expected = wide ? channel_value(i, 0, true) >> 8 : channel_value(i, source, false);
          EXPECT_EQ(rgb[3 * i + k], expected) << "pixel " << i << " channel " << k;
        }
      }
    }
  }
}

TEST_F(ImageDecoding, LabelImagesToMono8) {
  std::vector<std::uint8_t> labels;
  for (const auto& form : testing::forms_of(encoded("mono8"))) {
    image_to_mono8(decode_image(*form.bytes, form.serialization), labels);
    ASSERT_EQ(labels.size(), 6u);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(labels[i], channel_value(i, 0, false)) << form.form;
  }
  for (const auto& form : testing::forms_of(encoded("labels16"))) {  // big-endian 16-bit ids below 256
    image_to_mono8(decode_image(*form.bytes, form.serialization), labels);
    ASSERT_EQ(labels.size(), 6u);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(labels[i], 50 * i) << form.form;
  }
  const std::string e =
      error_of([&] { image_to_mono8(decode_image(encoded("mono16_be").ros1, Serialization::kRos1), labels); });
  EXPECT_NE(e.find("label 300 at row 0, column 0 does not fit in 8 bits"), std::string::npos) << e;
  const std::string colour =
      error_of([&] { image_to_mono8(decode_image(encoded("rgb8").cdr_le, Serialization::kCdr), labels); });
  EXPECT_NE(colour.find("\"rgb8\" is a colour image"), std::string::npos) << colour;
}

TEST_F(ImageDecoding, LayoutErrorsNameTheField) {
  for (const auto& form : testing::forms_of(encoded("bad_step"))) {
    const std::string e = error_of([&] { decode_image(*form.bytes, form.serialization); });
    EXPECT_NE(e.find("sensor_msgs/Image"), std::string::npos) << e;
    EXPECT_NE(e.find("field step at byte"), std::string::npos) << e;
    EXPECT_NE(e.find("8 is less than width 3 x 3 bytes per pixel"), std::string::npos) << e;
  }
  for (const auto& form : testing::forms_of(encoded("short_data"))) {
    const std::string e = error_of([&] { decode_image(*form.bytes, form.serialization); });
    EXPECT_NE(e.find("field data at byte"), std::string::npos) << e;
    EXPECT_NE(e.find("has 6 bytes where height 2 x step 4 = 8"), std::string::npos) << e;
  }
  // Encodings slamvdb does not read decode, and their conversion names them.
  const ImageView bayer = decode_image(encoded("bayer").cdr_be, Serialization::kCdr);
  EXPECT_EQ(bayer.encoding, "bayer_rggb8");
  std::vector<std::uint8_t> rgb;
  const std::string e = error_of([&] { image_to_rgb8(bayer, rgb); });
  EXPECT_NE(e.find("encoding \"bayer_rggb8\" is not supported"), std::string::npos) << e;
}

TEST_F(ImageDecoding, ImagesWithoutPixelsConvertToNothing) {
  std::vector<std::uint8_t> out(5, 1);
  for (const auto& form : testing::forms_of(encoded("empty"))) {
    const ImageView image = decode_image(*form.bytes, form.serialization);
    EXPECT_EQ(image.width, 0u);
    EXPECT_EQ(image.height, 2u);
    image_to_rgb8(image, out);
    EXPECT_TRUE(out.empty());
    out.assign(5, 1);
    image_to_mono8(image, out);
    EXPECT_TRUE(out.empty());
  }
}

TEST_F(ImageDecoding, CompressedImageIsAView) {
  for (const auto& form : testing::forms_of(encoded("compressed"))) {
    const CompressedImageView image = decode_compressed_image(*form.bytes, form.serialization);
    EXPECT_EQ(image.format, "jpeg");
    EXPECT_EQ(image.header.stamp_ns, 5'000000006);
    EXPECT_EQ(image.header.frame_id, "pylon_camera");
    EXPECT_EQ(std::vector<std::uint8_t>(image.data.begin(), image.data.end()),
              (std::vector<std::uint8_t>{0xff, 0xd8, 0xff, 0xe0, 1, 2, 3}));
    EXPECT_GE(image.data.data(), form.bytes->data());  // a view into the message, not a copy
    EXPECT_LE(image.data.data() + image.data.size(), form.bytes->data() + form.bytes->size());
  }
}

TEST_F(ImageDecoding, EveryTruncationIsAnError) {
  for (const std::string name : {"rgba8", "mono16_be", "compressed"}) {
    for (const auto& form : testing::forms_of(encoded(name))) {
      const auto& full = *form.bytes;
      for (std::size_t size = 0; size < full.size(); ++size) {
        const std::vector<std::uint8_t> cut(full.begin(), full.begin() + size);
        const std::string e = error_of([&] {
          if (name == "compressed")
            decode_compressed_image(cut, form.serialization);
          else
            decode_image(cut, form.serialization);
        });
        ASSERT_NE(e.find(" at byte "), std::string::npos) << name << " " << form.form << " cut to " << size << ": " << e;
      }
    }
  }
}

}  // namespace image_test
}  // namespace slamvdb::recording
