#include "slamvdb/eval/coverage_png.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/io/map_pictures.hpp"

namespace slamvdb {
namespace coverage_png {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kScale = 0.45;

void put_text(cv::Mat& img, const std::string& s, cv::Point at, const cv::Scalar& colour, bool centred = false,
              double scale = kScale) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(s, kFont, scale, 1, &baseline);
  if (centred) at.x -= size.width / 2;
  cv::putText(img, s, {at.x, at.y + size.height / 2}, kFont, scale, colour, 1, cv::LINE_AA);
}

// Distinct in colour and in marker (readable in grey too), RGB.
const cv::Scalar kLineColours[] = {{31, 119, 180}, {255, 127, 14}, {44, 160, 44}, {214, 39, 40}, {148, 103, 189}};

}  // namespace coverage_png

std::vector<double> coverage_plot_fractions() {
  std::vector<double> f;
  for (int i = 1; i <= 20; ++i) f.push_back(i / 20.0);
  return f;
}

cv::Mat render_coverage_plot(const std::vector<NamedCoverage>& curves, const std::string& title) {
  namespace cp = coverage_png;
  if (curves.empty()) throw Error("coverage plot: no curve");
  double lo = 1.0;
  for (const NamedCoverage& c : curves) {
    if (c.curve.empty()) throw Error(fmt::format("coverage plot: curve '{}' has no point", c.name));
    for (const CoveragePoint& p : c.curve) lo = std::min(lo, p.accuracy);
  }
  // The accuracy axis from a round 10 % below the lowest point to 100 %.
  const double y0 = std::clamp(std::floor(lo * 10.0 - 1e-9) / 10.0, 0.0, 0.9), y1 = 1.0;
  const int width = 720, height = 480, left = 70, right = 20, top = title.empty() ? 20 : 44, bottom = 60;
  const int pw = width - left - right, ph = height - top - bottom;
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Scalar black(0, 0, 0), grid(225, 225, 225), grey(110, 110, 110);
  const auto px = [&](double fraction, double accuracy) {
    return cv::Point(left + static_cast<int>(std::lround(fraction * pw)),
                     top + static_cast<int>(std::lround((y1 - accuracy) / (y1 - y0) * ph)));
  };
  if (!title.empty()) cp::put_text(img, title, {width / 2, 18}, black, true, 0.55);
  for (int i = 0; i <= 10; ++i) {  // grid and ticks
    const double f = i / 10.0, a = y0 + (y1 - y0) * i / 10.0;
    cv::line(img, px(f, y0), px(f, y1), grid);
    cv::line(img, px(0, a), px(1, a), grid);
    cp::put_text(img, fmt::format("{:.0f}", 100 * f), px(f, y0) + cv::Point(0, 14), black, true);
    cp::put_text(img, fmt::format("{:.0f}", 100 * a), px(0, a) + cv::Point(-34, 0), black);
  }
  cv::rectangle(img, px(0, y1), px(1, y0), black, 1);
  cp::put_text(img, "most confident voxels (% of the scored voxels)", {left + pw / 2, height - 22}, grey, true);
  cv::Mat label(20, ph, CV_8UC3, cv::Scalar(255, 255, 255));  // the y label, drawn then rotated
  cp::put_text(label, "voxel accuracy (%)", {ph / 2, 9}, grey, true);
  cv::rotate(label, label, cv::ROTATE_90_COUNTERCLOCKWISE);
  label.copyTo(img(cv::Rect(4, top, label.cols, label.rows)));

  for (std::size_t k = 0; k < curves.size(); ++k) {
    const cv::Scalar colour = cp::kLineColours[k % std::size(cp::kLineColours)];
    std::vector<cv::Point> line;
    for (const CoveragePoint& p : curves[k].curve) line.push_back(px(p.fraction, p.accuracy));
    cv::polylines(img, line, false, colour, 2, cv::LINE_AA);
    for (const cv::Point& p : line)
      if (k % 2 == 0) cv::circle(img, p, 4, colour, cv::FILLED, cv::LINE_AA);
      else cv::rectangle(img, p - cv::Point(4, 4), p + cv::Point(4, 4), colour, cv::FILLED);
    // Legend, bottom left inside the plot (the curves fall from the top left).
    const cv::Point at = px(0.03, y0) + cv::Point(0, -18 * static_cast<int>(curves.size() - k));
    cv::line(img, at, at + cv::Point(24, 0), colour, 2, cv::LINE_AA);
    cp::put_text(img, curves[k].name, at + cv::Point(30, 0), black);
  }
  return img;
}

void write_coverage_png(const std::filesystem::path& file, const std::vector<NamedCoverage>& curves,
                        const std::string& title) {
  write_image_atomically(file, render_coverage_plot(curves, title));
}

}  // namespace slamvdb
