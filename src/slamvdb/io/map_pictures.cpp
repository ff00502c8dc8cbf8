#include "slamvdb/io/map_pictures.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/image_codecs.hpp"

namespace slamvdb {
namespace {

const cv::Scalar kInk(255, 255, 255), kPanel(20, 24, 28);
constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;

// A round length of at most `max_m` metres for the scale bar: 1, 2 or 5 times a power of ten.
double round_length(double max_m) {
  const double p = std::pow(10.0, std::floor(std::log10(max_m)));
  for (const double f : {5.0, 2.0, 1.0})
    if (f * p <= max_m) return f * p;
  return p;
}

void panel(cv::Mat& m, cv::Rect r) {
  r &= cv::Rect(0, 0, m.cols, m.rows);
  if (r.area() <= 0) return;
  cv::Mat roi = m(r);
  cv::Mat dark(roi.size(), roi.type(), kPanel);
  cv::addWeighted(roi, 0.35, dark, 0.65, 0.0, roi);
}

}  // namespace

const std::array<Rgb, 256>& score_colour_ramp() {
  static const std::array<Rgb, 256> ramp = [] {
    cv::Mat grey(1, 256, CV_8UC1), bgr;
    for (int i = 0; i < 256; ++i) grey.at<uint8_t>(0, i) = static_cast<uint8_t>(i);
    cv::applyColorMap(grey, bgr, cv::COLORMAP_VIRIDIS);
    std::array<Rgb, 256> r{};
    for (int i = 0; i < 256; ++i) {
      const cv::Vec3b c = bgr.at<cv::Vec3b>(0, i);
      r[i] = {c[2], c[1], c[0]};
    }
    return r;
  }();
  return ramp;
}

Rgb score_colour(float t) {
  const float clamped = std::isfinite(t) ? std::clamp(t, 0.0f, 1.0f) : 0.0f;
  return score_colour_ramp()[static_cast<std::size_t>(std::lround(clamped * 255.0f))];
}

void hatch(BirdsEyeImage& image, const cv::Mat& mask) {
  if (mask.empty()) return;
  if (mask.size() != image.rgb.size() || mask.type() != CV_8UC1)
    throw Error(fmt::format("hatch mask {}x{} does not match the {}x{} picture", mask.cols, mask.rows, image.rgb.cols,
                            image.rgb.rows));
  // A period of 6 px (at least 2 lines per enlarged voxel) keeps 4 of 6 pixels' colour.
  for (int r = 0; r < mask.rows; ++r)
    for (int c = 0; c < mask.cols; ++c)
      if (mask.at<uint8_t>(r, c) && (r + c) % 6 < 2) image.rgb.at<cv::Vec3b>(r, c) = {kHatchColour[0], kHatchColour[1], kHatchColour[2]};
}

std::string uncertain_legend(float min_confidence) {
  return fmt::format("uncertain (confidence < {:.3g}): hatched, unknown to the planner", min_confidence);
}

void annotate(BirdsEyeImage& image, const PictureAnnotations& a) {
  // A small map is enlarged (whole pixels, the resolution follows) so that the annotations do
  // not cover it and text stays readable.
  cv::Mat hatched = a.hatched;
  if (const int longest = std::max(image.rgb.cols, image.rgb.rows); longest > 0 && longest < 600) {
    const int k = std::min(8, (600 + longest - 1) / longest);
    cv::resize(image.rgb, image.rgb, cv::Size(), k, k, cv::INTER_NEAREST);
    if (!hatched.empty()) cv::resize(hatched, hatched, cv::Size(), k, k, cv::INTER_NEAREST);
    image.resolution /= k;
  }
  hatch(image, hatched);
  cv::Mat& m = image.rgb;  // RGB order: cv::Scalar(r, g, b)
  const double scale = std::clamp(m.cols / 900.0, 0.35, 0.8);  // font scale for the picture's size
  const int line = static_cast<int>(std::lround(26 * scale / 0.6)), pad = 6;
  if (a.trajectory.size() >= 2) {
    std::vector<cv::Point> path;
    for (const auto& p : a.trajectory) {
      const Eigen::Vector2i px = image.pixel_of(p.x(), p.y());
      path.emplace_back(px.x(), m.rows - 1 - px.y());
    }
    cv::polylines(m, path, false, cv::Scalar(255, 60, 60), std::max(1, m.cols / 500), cv::LINE_AA);
    cv::circle(m, path.front(), 4, cv::Scalar(255, 60, 60), cv::FILLED);
  }
  // Top left: title, legend or colour bar.
  std::vector<std::string> rows;
  if (!a.title.empty()) rows.push_back(a.title);
  int width = 0;
  for (const auto& [name, colour] : a.legend)
    width = std::max(width, cv::getTextSize(name, kFont, scale, 1, nullptr).width + line + pad);
  if (!a.title.empty()) width = std::max(width, cv::getTextSize(a.title, kFont, scale, 1, nullptr).width);
  if (a.colour_bar)
    width = std::max({width, 220, cv::getTextSize(a.colour_bar->label, kFont, scale * 0.9, 1, nullptr).width});
  const int bar_rows = a.colour_bar ? 3 : 0;
  const int box_h = pad * 2 + line * static_cast<int>(rows.size() + a.legend.size() + bar_rows);
  if (box_h > 2 * pad) {
    panel(m, cv::Rect(0, 0, width + 2 * pad, box_h));
    int y = pad + line - line / 4;
    if (!a.title.empty()) cv::putText(m, a.title, {pad, y}, kFont, scale, kInk, 1, cv::LINE_AA), y += line;
    for (const auto& [name, colour] : a.legend) {
      cv::rectangle(m, cv::Rect(pad, y - line + line / 3, line - 4, line - 6), cv::Scalar(colour[0], colour[1], colour[2]),
                    cv::FILLED);
      cv::putText(m, name, {pad + line + 2, y}, kFont, scale, kInk, 1, cv::LINE_AA);
      y += line;
    }
    if (a.colour_bar) {
      cv::putText(m, a.colour_bar->label, {pad, y}, kFont, scale * 0.9, kInk, 1, cv::LINE_AA);
      y += line;
      const int x0 = pad, bar_w = width, top = y - line + line / 3;
      for (int i = 0; i < bar_w; ++i) {
        const Rgb c = score_colour_ramp()[static_cast<std::size_t>(i * 255 / std::max(1, bar_w - 1))];
        cv::line(m, {x0 + i, top}, {x0 + i, top + line - 6}, cv::Scalar(c[0], c[1], c[2]));
      }
      y += line;
      const std::string lo = fmt::format("{:.2f}", a.colour_bar->min), hi = fmt::format("{:.2f}", a.colour_bar->max);
      cv::putText(m, lo, {x0, y}, kFont, scale, kInk, 1, cv::LINE_AA);
      const int hi_w = cv::getTextSize(hi, kFont, scale, 1, nullptr).width;
      cv::putText(m, hi, {x0 + bar_w - hi_w, y}, kFont, scale, kInk, 1, cv::LINE_AA);
    }
  }
  // Bottom left: a scale bar of a round length, about a fifth of the width.
  if (a.scale_bar) {
    const double metres = round_length(0.2 * m.cols * image.resolution);
    const int px = std::max(1, static_cast<int>(std::lround(metres / image.resolution)));
    const std::string text = metres >= 1 ? fmt::format("{:g} m", metres) : fmt::format("{:g} cm", metres * 100);
    panel(m, cv::Rect(0, m.rows - 2 * line - pad, px + 2 * pad + 4, 2 * line + pad));
    const int y = m.rows - pad - line / 2;
    cv::line(m, {pad, y}, {pad + px, y}, kInk, 2);
    cv::line(m, {pad, y - 5}, {pad, y + 5}, kInk, 2);
    cv::line(m, {pad + px, y - 5}, {pad + px, y + 5}, kInk, 2);
    cv::putText(m, text, {pad, y - 8}, kFont, scale, kInk, 1, cv::LINE_AA);
  }
  // Top right: north (world +y is up in the picture).
  if (a.north_arrow) {
    const int x = m.cols - pad - line, top = pad + line + 4;
    panel(m, cv::Rect(m.cols - 2 * line - pad, 0, 2 * line + pad, 3 * line));
    cv::arrowedLine(m, {x, top + line + line / 2}, {x, top}, kInk, 2, cv::LINE_AA, 0, 0.35);
    cv::putText(m, "N (+y)", {x - line + 2, top - 6}, kFont, scale * 0.7, kInk, 1, cv::LINE_AA);
  }
}

std::string map_server_yaml(const std::string& image_file, double resolution, const Eigen::Vector2d& origin,
                            const std::string& mode) {
  return fmt::format(
      "# ROS map_server / Nav2 map (written by slamvdb): the lower-left pixel's corner is at origin (world frame)\n"
      "image: {}\nmode: {}\nresolution: {:.6f}\norigin: [{:.6f}, {:.6f}, 0.0]\nnegate: 0\noccupied_thresh: 0.65\n"
      "free_thresh: 0.196\n",
      image_file, mode, resolution, origin.x(), origin.y());
}

void write_image_atomically(const std::filesystem::path& path, const cv::Mat& image) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
  if (extension != ".png" && extension != ".pgm")
    throw Error(fmt::format("{}: images are written as .png or .pgm", path.string()));
  cv::Mat out = image;
  if (image.channels() == 3) cv::cvtColor(image, out, cv::COLOR_RGB2BGR);
  std::vector<uint8_t> bytes;
  if (!encode_image(extension, out, bytes)) throw Error(fmt::format("cannot encode {}", path.string()));
  write_output_file(path, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

std::filesystem::path map_server_yaml_path(const std::filesystem::path& png) {
  return std::filesystem::path(png).replace_extension(".yaml");
}

void write_png_with_yaml(const std::filesystem::path& png, const BirdsEyeImage& image) {
  write_image_atomically(png, image.rgb);
  const std::filesystem::path yaml = map_server_yaml_path(png);
  write_output_file(yaml, map_server_yaml(png.filename().string(), image.resolution, image.min_xy));
}

}  // namespace slamvdb
