#include "slamvdb/eval/confusion_png.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/image_codecs.hpp"

namespace slamvdb {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kScale = 0.45;
constexpr int kPad = 8;

int text_width(const std::string& s, double scale = kScale) {
  int baseline = 0;
  return cv::getTextSize(s, kFont, scale, 1, &baseline).width;
}

void put_text(cv::Mat& img, const std::string& s, cv::Point centre, const cv::Scalar& colour, double scale = kScale) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(s, kFont, scale, 1, &baseline);
  cv::putText(img, s, {centre.x - size.width / 2, centre.y + size.height / 2}, kFont, scale, colour, 1, cv::LINE_AA);
}

// Viridis: readable for colour-blind viewers and monotonic in lightness.
cv::Vec3b share_colour(double share) {
  cv::Mat v(1, 1, CV_8UC1, cv::Scalar(std::clamp(static_cast<int>(share * 255.0 + 0.5), 0, 255))), c;
  cv::applyColorMap(v, c, cv::COLORMAP_VIRIDIS);
  return c.at<cv::Vec3b>(0, 0);
}

}  // namespace

cv::Mat render_confusion_matrix(const ConfusionMatrix& m, const std::string& title) {
  std::vector<int> rows, cols;
  for (int k = 0; k < m.num_classes(); ++k)
    if (!m.is_ignored(k)) rows.push_back(k);
  bool any_none = false;
  for (int k : rows) any_none |= m.count(k, ConfusionMatrix::kNoPrediction) > 0;
  for (int k = 0; k < m.num_classes(); ++k)
    if (!m.is_ignored(k) || m.recalled(k) > 0) cols.push_back(k);
  if (any_none) cols.push_back(ConfusionMatrix::kNoPrediction);
  const auto name = [&](int k) { return k == ConfusionMatrix::kNoPrediction ? std::string("none") : m.class_names()[k]; };

  int label_w = text_width("ground truth");
  for (int k : rows) label_w = std::max(label_w, text_width(name(k)));
  int cell_w = text_width("100.0%") + 2 * kPad;
  for (int k : cols) cell_w = std::max(cell_w, text_width(name(k)) + 2 * kPad);
  const int cell_h = 44, left = label_w + 2 * kPad, top = (title.empty() ? 0 : 30) + 50;
  const int bar_w = 20, bar_x = left + cell_w * static_cast<int>(cols.size()) + 3 * kPad;
  const int width = bar_x + bar_w + text_width("100%") + 3 * kPad;
  const int height = top + cell_h * std::max<int>(static_cast<int>(rows.size()), 4) + 2 * kPad + 20;
  cv::Mat img(height, width, CV_8UC3, cv::Scalar(255, 255, 255));
  const cv::Scalar black(0, 0, 0), white(255, 255, 255), grey(120, 120, 120);

  if (!title.empty()) put_text(img, title, {width / 2, 18}, black, 0.55);
  put_text(img, "predicted", {left + cell_w * static_cast<int>(cols.size()) / 2, top - 38}, grey);
  put_text(img, "ground truth", {left / 2, top - 12}, grey);
  for (std::size_t c = 0; c < cols.size(); ++c)
    put_text(img, name(cols[c]), {left + cell_w * static_cast<int>(c) + cell_w / 2, top - 12}, black);
  for (std::size_t r = 0; r < rows.size(); ++r) {
    const int y = top + cell_h * static_cast<int>(r);
    put_text(img, name(rows[r]), {left / 2, y + cell_h / 2}, black);
    const uint64_t total = m.relevant(rows[r]);
    for (std::size_t c = 0; c < cols.size(); ++c) {
      const uint64_t n = m.count(rows[r], cols[c]);
      const double share = total ? static_cast<double>(n) / total : 0.0;
      const cv::Rect cell(left + cell_w * static_cast<int>(c), y, cell_w, cell_h);
      img(cell).setTo(share_colour(share));
      cv::rectangle(img, cell, rows[r] == cols[c] ? black : white, rows[r] == cols[c] ? 2 : 1);
      const cv::Scalar ink = share > 0.6 ? black : white;  // viridis is light at the top
      put_text(img, fmt::format("{}", n), {cell.x + cell_w / 2, y + cell_h / 3}, ink);
      put_text(img, total ? fmt::format("{:.1f}%", 100.0 * share) : "-", {cell.x + cell_w / 2, y + 2 * cell_h / 3}, ink);
    }
  }
  // Colour bar: share of the ground-truth row.
  const int bar_top = top, bar_h = cell_h * std::max<int>(static_cast<int>(rows.size()), 4);
  for (int y = 0; y < bar_h; ++y) img(cv::Rect(bar_x, bar_top + y, bar_w, 1)).setTo(share_colour(1.0 - double(y) / (bar_h - 1)));
  cv::rectangle(img, cv::Rect(bar_x, bar_top, bar_w, bar_h), black, 1);
  for (int pct : {0, 50, 100}) {
    const int y = bar_top + (bar_h - 1) * (100 - pct) / 100;
    cv::putText(img, fmt::format("{}%", pct), {bar_x + bar_w + 4, y + 5}, kFont, kScale, black, 1, cv::LINE_AA);
  }
  put_text(img, "share of the ground-truth row", {width / 2, height - 12}, grey);
  return img;
}

void write_confusion_png(const std::filesystem::path& file, const ConfusionMatrix& matrix, const std::string& title) {
  const cv::Mat img = render_confusion_matrix(matrix, title);
  // Encoded in memory and written by the one output writer (any path: a device too), not by
  // cv::imwrite, which neither says why a write failed nor writes atomically.
  std::vector<uchar> png;
  try {
    if (!encode_image(".png", img, png)) throw Error(fmt::format("cannot encode {} as PNG", file.string()));
  } catch (const cv::Exception& e) {
    throw Error(fmt::format("cannot encode {} as PNG: {}", file.string(), e.what()));
  }
  write_output_file(file, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

}  // namespace slamvdb
