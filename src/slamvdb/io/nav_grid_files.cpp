#include "slamvdb/io/nav_grid_files.hpp"

#include <fmt/format.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/image_codecs.hpp"

namespace slamvdb {

NavGridFiles nav_grid_files(const std::filesystem::path& prefix) {
  return {prefix.string() + ".pgm", prefix.string() + ".yaml", prefix.string() + ".png"};
}

namespace {

// An 8-bit image (RGB or grey) encoded as `extension` (".png", ".pgm").
std::string encoded_image(const cv::Mat& image, const char* extension) {
  cv::Mat out = image;
  if (image.channels() == 3) cv::cvtColor(image, out, cv::COLOR_RGB2BGR);
  std::vector<uint8_t> bytes;
  if (!encode_image(extension, out, bytes)) throw Error(fmt::format("cannot encode the navigation grid as {}", extension));
  return {reinterpret_cast<const char*>(bytes.data()), bytes.size()};
}

}  // namespace

std::vector<Rgb> class_colours(const QuerySet& queries) {
  std::vector<Rgb> colours;
  for (int k = 0; k < queries.size(); ++k)
    colours.push_back(queries.colours.empty() ? score_colour(queries.size() > 1 ? k / (queries.size() - 1.0f) : 0.f)
                                              : queries.colours[k]);
  return colours;
}

NavGridFiles write_nav_grid(const std::filesystem::path& prefix, const NavGrid& grid,
                            const std::vector<std::string>& class_names, const std::vector<Rgb>& class_colours,
                            const std::vector<Eigen::Vector2d>& trajectory, float min_confidence) {
  const NavGridFiles files = nav_grid_files(prefix);
  const NavGridBytes bytes =
      encode_nav_grid(grid, files.pgm.filename().string(), class_names, class_colours, trajectory, min_confidence);
  write_output_file(files.pgm, bytes.pgm);
  write_output_file(files.yaml, bytes.yaml);
  write_output_file(files.png, bytes.png);
  return files;
}

NavGridBytes encode_nav_grid(const NavGrid& grid, const std::string& pgm_name,
                             const std::vector<std::string>& class_names, const std::vector<Rgb>& class_colours,
                             const std::vector<Eigen::Vector2d>& trajectory, float min_confidence) {
  if (grid.width <= 0 || grid.height <= 0) throw Error("the navigation grid is empty");
  // Image rows run north to south; grid rows south to north.
  cv::Mat pgm(grid.height, grid.width, CV_8UC1);
  BirdsEyeImage picture;
  picture.rgb = cv::Mat(grid.height, grid.width, CV_8UC3);
  picture.resolution = grid.resolution;
  picture.min_xy = grid.origin;
  std::vector<bool> shown(class_names.size(), false);
  cv::Mat hatched;  // uncertain ground: its class colour, hatched
  std::size_t uncertain = 0;
  if (!grid.uncertain.empty()) hatched = cv::Mat::zeros(grid.height, grid.width, CV_8UC1);
  for (int row = 0; row < grid.height; ++row)
    for (int col = 0; col < grid.width; ++col) {
      const std::size_t i = grid.index(col, row);
      const int image_row = grid.height - 1 - row;
      pgm.at<uint8_t>(image_row, col) = nav_pgm_value(grid.cost[i]);
      Rgb c{110, 110, 110};  // unknown
      if (grid.obstacle[i]) {
        c = {0, 0, 0};
      } else if (const int k = grid.ground_class[i];
                 k >= 0 && static_cast<std::size_t>(k) < class_colours.size() &&
                 (grid.cost[i] != kUnknownCost || (!grid.uncertain.empty() && grid.uncertain[i]))) {
        c = class_colours[static_cast<std::size_t>(k)];
        if (static_cast<std::size_t>(k) < shown.size()) shown[static_cast<std::size_t>(k)] = true;
        if (!grid.uncertain.empty() && grid.uncertain[i]) hatched.at<uint8_t>(image_row, col) = 1, ++uncertain;
      }
      picture.rgb.at<cv::Vec3b>(image_row, col) = {c[0], c[1], c[2]};
    }
  NavGridBytes out;
  out.pgm = encoded_image(pgm, ".pgm");
  out.yaml = map_server_yaml(pgm_name, grid.resolution, grid.origin, "raw");

  PictureAnnotations notes;
  notes.title = "navigation grid";
  for (std::size_t k = 0; k < class_names.size() && k < class_colours.size(); ++k)
    if (shown[k]) notes.legend.emplace_back(class_names[k], class_colours[k]);
  notes.legend.emplace_back("obstacle within robot height", Rgb{0, 0, 0});
  notes.legend.emplace_back("unknown (not seen, or no class)", Rgb{110, 110, 110});
  if (uncertain)
    notes.legend.emplace_back(uncertain_legend(min_confidence), kHatchColour);
  notes.hatched = hatched;
  if (trajectory.size() >= 2) notes.legend.emplace_back("path (submap anchors)", Rgb{255, 60, 60});
  notes.trajectory = trajectory;
  annotate(picture, notes);
  out.png = encoded_image(picture.rgb, ".png");
  return out;
}

}  // namespace slamvdb
