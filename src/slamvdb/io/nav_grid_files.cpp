#include "slamvdb/io/nav_grid_files.hpp"

#include <fmt/format.h>

#include <opencv2/core.hpp>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/output_file.hpp"

namespace slamvdb {

NavGridFiles nav_grid_files(const std::filesystem::path& prefix) {
  return {prefix.string() + ".pgm", prefix.string() + ".yaml", prefix.string() + ".png"};
}

NavGridFiles write_nav_grid(const std::filesystem::path& prefix, const NavGrid& grid,
                            const std::vector<std::string>& class_names, const std::vector<Rgb>& class_colours,
                            const std::vector<Eigen::Vector2d>& trajectory, float min_confidence) {
  if (grid.width <= 0 || grid.height <= 0) throw Error("the navigation grid is empty");
  const NavGridFiles files = nav_grid_files(prefix);
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
  write_image_atomically(files.pgm, pgm);
  write_output_file(files.yaml, map_server_yaml(files.pgm.filename().string(), grid.resolution, grid.origin, "raw"));

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
  write_image_atomically(files.png, picture.rgb);
  return files;
}

}  // namespace slamvdb
