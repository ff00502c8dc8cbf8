// Image questions over HTTP (issue 21: POST /api/query "image", a base64 PNG or JPEG in JSON):
// a real `slamvdb serve` answers exactly what `slamvdb query --image FILE` answers on the same map
// (the same encoder choice and embedding, io/query_image.hpp; here the SIMULATED encoder on a 2D
// label image), alone, with other terms and as a data URL; bad base64, bytes that are no image, an
// image of too many pixels (from its header, nothing decoded) and a label image of unknown ids are
// each a 400 naming `image`; decode_base64 is strict RFC 4648.
#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "slamvdb/core/ontology.hpp"
#include "slamvdb/server/request_decoding.hpp"
#include "slamvdb/testing/served_map.hpp"

namespace slamvdb {
namespace {

using testing::query_answer_rows;
using testing::ServedMap;
using testing::shell_quote;

std::string base64(std::string_view bytes) {
  static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  for (std::size_t i = 0; i < bytes.size(); i += 3) {
    uint32_t v = static_cast<uint8_t>(bytes[i]) << 16;
    if (i + 1 < bytes.size()) v |= static_cast<uint8_t>(bytes[i + 1]) << 8;
    if (i + 2 < bytes.size()) v |= static_cast<uint8_t>(bytes[i + 2]);
    out += kAlphabet[(v >> 18) & 63];
    out += kAlphabet[(v >> 12) & 63];
    out += i + 1 < bytes.size() ? kAlphabet[(v >> 6) & 63] : '=';
    out += i + 2 < bytes.size() ? kAlphabet[v & 63] : '=';
  }
  return out;
}

TEST(DecodeBase64, StrictRfc4648WithOptionalPaddingAndDataUrl) {
  EXPECT_EQ(decode_base64("aGVsbG8="), "hello");
  EXPECT_EQ(decode_base64("aGVsbG8"), "hello");  // padding optional
  EXPECT_EQ(decode_base64("aGVsbG8h"), "hello!");
  EXPECT_EQ(decode_base64("data:image/png;base64,aGk="), "hi");
  EXPECT_EQ(decode_base64(""), "");
  const std::string all = [] {
    std::string s;
    for (int c = 0; c < 256; ++c) s += static_cast<char>(c);
    return s;
  }();
  EXPECT_EQ(decode_base64(base64(all)), all);
  for (const char* bad : {"aGVsbG8==", "aGVsbG8=x", "a", "aGV sbG8=", "aGVs\nbG8=", "aGk_", "aGl=", "data:image/png,aGk=",
                          "=", "a===", "aGk=="})
    EXPECT_FALSE(decode_base64(bad)) << bad;
}

// A 2D label image (8-bit RELLIS-3D ids: the SIMULATED image encoder's input), left half one
// class, right half another, as a PNG file and its bytes.
std::string label_png(const std::filesystem::path& file, int width, int height) {
  cv::Mat labels(height, width, CV_8UC1, cv::Scalar(rellis_classes()[3].id));
  labels.colRange(0, width / 3).setTo(cv::Scalar(rellis_classes()[1].id));
  std::vector<uint8_t> png;
  EXPECT_TRUE(cv::imencode(".png", labels, png));
  std::ofstream(file, std::ios::binary).write(reinterpret_cast<const char*>(png.data()), static_cast<std::streamsize>(png.size()));
  return {png.begin(), png.end()};
}

TEST(ServeImage, AnImageQueryEqualsQueryImageAndBadImagesAre400NamingImage) {
  ServedMap s;  // SIMULATED encoders, --ignore-model-id (the map is in a 4-d test space)
  ASSERT_GT(s.server.port(), 0) << s.server.output() << "\n" << s.log();
  const auto file = s.f.tmp.path / "labels.png";
  const std::string png = label_png(file, 24, 16);
  const std::string b64 = base64(png);
  const std::string image = shell_quote(file.string());
  const std::vector<std::pair<nlohmann::json, std::string>> cases = {
      {{{"image", b64}, {"top_k", 9}}, "--image " + image + " --top-k 9"},
      {{{"image", {"data:image/png;base64," + b64}}, {"text", "grass"}, {"top_k", 6}},
       "--image " + image + " --text grass --top-k 6"},
      {{{"image", {b64, b64}}, {"not_class", "rough"}, {"top_k", 0}, {"threshold", -1}},
       "--image " + image + " --image " + image + " --not-class rough --top-k 0 --threshold=-1"},
  };
  for (const auto& [body, args] : cases) {
    const nlohmann::json answer = s.post_query(body);
    ASSERT_TRUE(answer.contains("results")) << body.dump() << "\n" << s.log();
    EXPECT_TRUE(answer.at("image_encoder").at("simulated").get<bool>());
    const auto expected = s.cli_rows(args);
    ASSERT_FALSE(expected.empty()) << args;
    EXPECT_EQ(query_answer_rows(answer), expected) << args;
  }

  // Refusals, each naming the field.
  std::string huge = png;  // the PNG's IHDR says 100000 x 100000: refused from the header
  for (const int at : {16, 20}) huge[at] = 0, huge[at + 1] = 0x01, huge[at + 2] = static_cast<char>(0x86), huge[at + 3] = static_cast<char>(0xA0);
  cv::Mat unknown(8, 8, CV_8UC1, cv::Scalar(250));  // no RELLIS-3D class has id 250
  std::vector<uint8_t> unknown_png;
  ASSERT_TRUE(cv::imencode(".png", unknown, unknown_png));
  for (const nlohmann::json& body :
       {nlohmann::json{{"image", "not base64!"}}, nlohmann::json{{"image", base64("hello, not an image")}},
        nlohmann::json{{"image", base64(huge)}}, nlohmann::json{{"image", base64(std::string(unknown_png.begin(), unknown_png.end()))}},
        nlohmann::json{{"image", 7}}, nlohmann::json{{"image", ""}}}) {
    const nlohmann::json refused = s.post_query(body, 400);
    ASSERT_TRUE(refused.contains("error")) << body.dump().substr(0, 80);
    EXPECT_EQ(refused.at("error").at("field"), "image") << refused;
  }
  EXPECT_EQ(s.server.stop(SIGTERM), 0) << s.log();
}

}  // namespace
}  // namespace slamvdb
