#include "slamvdb/io/trajectory_plot.hpp"

#include <fmt/format.h>
#include <fmt/std.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/image_codecs.hpp"

namespace slamvdb {

void write_trajectory_plot(const std::filesystem::path& png, const std::vector<PlotLine>& lines,
                           const std::vector<std::pair<Vec3d, Vec3d>>& edges, int size_px) {
  Eigen::AlignedBox2d box;
  for (const auto& l : lines)
    for (const Vec3d& p : l.positions) box.extend(p.head<2>());
  if (box.isEmpty()) throw Error(fmt::format("cannot plot {}: no positions", png));
  const int margin = 60;
  const double extent = std::max({box.sizes().x(), box.sizes().y(), 1.0});
  const double scale = (size_px - 2 * margin) / extent;  // pixels per metre
  const Eigen::Vector2d centre = box.center();
  const auto pixel = [&](const Vec3d& p) {
    return cv::Point(static_cast<int>(std::lround(size_px / 2.0 + (p.x() - centre.x()) * scale)),
                     static_cast<int>(std::lround(size_px / 2.0 - (p.y() - centre.y()) * scale)));
  };
  cv::Mat image(size_px, size_px, CV_8UC3, cv::Scalar(255, 255, 255));
  for (const auto& [a, b] : edges) cv::line(image, pixel(a), pixel(b), cv::Scalar(0, 160, 0), 1, cv::LINE_AA);
  const auto mark_loops = [&] {  // drawn again over the lines: a loop's two ends are often one place
    for (const auto& [a, b] : edges)
      for (const Vec3d& p : {a, b}) cv::circle(image, pixel(p), 4, cv::Scalar(0, 160, 0), 1, cv::LINE_AA);
  };
  for (const auto& l : lines) {
    const cv::Scalar colour(l.rgb[2], l.rgb[1], l.rgb[0]);
    for (std::size_t i = 1; i < l.positions.size(); ++i)
      cv::line(image, pixel(l.positions[i - 1]), pixel(l.positions[i]), colour, 2, cv::LINE_AA);
    if (!l.positions.empty()) cv::circle(image, pixel(l.positions.front()), 5, colour, cv::FILLED);
  }
  mark_loops();
  // Legend.
  int y = 25;
  for (const auto& l : lines) {
    cv::line(image, {15, y - 5}, {45, y - 5}, cv::Scalar(l.rgb[2], l.rgb[1], l.rgb[0]), 3);
    cv::putText(image, l.label, {55, y}, cv::FONT_HERSHEY_SIMPLEX, 0.55, cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
    y += 22;
  }
  if (!edges.empty()) {
    cv::line(image, {15, y - 5}, {45, y - 5}, cv::Scalar(0, 160, 0), 1);
    cv::putText(image, fmt::format("loop closures ({})", edges.size()), {55, y}, cv::FONT_HERSHEY_SIMPLEX, 0.55,
                cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  }
  // Scale bar: a round length near a fifth of the plot.
  const double target = extent / 5.0;
  const double magnitude = std::pow(10.0, std::floor(std::log10(target)));
  double bar = magnitude;
  for (const double f : {2.0, 5.0, 10.0})
    if (f * magnitude <= target) bar = f * magnitude;
  const int bar_px = static_cast<int>(std::lround(bar * scale));
  const cv::Point origin(size_px - margin - bar_px, size_px - 25);
  cv::line(image, origin, origin + cv::Point(bar_px, 0), cv::Scalar(0, 0, 0), 2);
  cv::putText(image, fmt::format("{:g} m", bar), origin + cv::Point(0, -8), cv::FONT_HERSHEY_SIMPLEX, 0.55,
              cv::Scalar(0, 0, 0), 1, cv::LINE_AA);
  // Encoded in memory and written by the one output writer (core/output_file.hpp).
  std::vector<uchar> bytes;
  try {
    if (!encode_image(".png", image, bytes)) throw Error(fmt::format("cannot encode {} as PNG", png));
  } catch (const cv::Exception& e) {
    throw Error(fmt::format("cannot encode {} as PNG: {}", png, e.what()));
  }
  write_output_file(png, std::string_view(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
}

}  // namespace slamvdb
