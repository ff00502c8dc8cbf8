#pragma once
// Pictures people can read: a bird's-eye image with a legend or a colour bar, a scale bar, a
// north arrow and the driven trajectory, written as PNG with a ROS map_server / Nav2 YAML beside
// it (resolution, origin), so that every pixel can be placed back in the world.
#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "slamvdb/io/map_export.hpp"

namespace slamvdb {

// A perceptually uniform colour ramp (OpenCV's viridis): index 0 (low) .. 255 (high).
const std::array<Rgb, 256>& score_colour_ramp();
Rgb score_colour(float t);  // t in [0, 1], clamped

struct PictureAnnotations {
  std::string title;
  std::vector<std::pair<std::string, Rgb>> legend;  // name and colour, drawn as swatches
  struct ColourBar {
    std::string label;
    double min = 0, max = 1;  // the ramp's ends (score_colour_ramp)
  };
  std::optional<ColourBar> colour_bar;
  std::vector<Eigen::Vector2d> trajectory;  // world x, y, drawn as a line (the driven path)
  // CV_8UC1 of the picture's size before annotate enlarges it: nonzero pixels are drawn hatched
  // (hatch(); e.g. uncertain terrain). Empty: none. A legend line says what it means.
  cv::Mat hatched;
  bool scale_bar = true, north_arrow = true;
};

// Dark diagonal lines over the pixels where `mask` (CV_8UC1, the image's size) is nonzero: the
// colour underneath stays readable between them.
void hatch(BirdsEyeImage& image, const cv::Mat& mask);
// The legend swatch of hatched areas (the lines' colour).
inline constexpr Rgb kHatchColour{30, 30, 30};
// The legend line of hatched uncertain terrain (classify --min-confidence).
std::string uncertain_legend(float min_confidence);

// Draws the annotations onto the picture. A picture under 600 pixels is first enlarged by a whole
// factor (its resolution follows, so pixel_of() and the YAML keep holding).
void annotate(BirdsEyeImage& image, const PictureAnnotations& annotations);

// PNG written atomically (encoded in memory first), and `<png stem>.yaml` beside it in the
// map_server form: image, mode, resolution, origin [x, y, yaw], negate, occupied/free thresholds.
void write_png_with_yaml(const std::filesystem::path& png, const BirdsEyeImage& image);
// The YAML written beside `png`.
std::filesystem::path map_server_yaml_path(const std::filesystem::path& png);
// The YAML text for an image file of the given resolution and lower-left world corner.
std::string map_server_yaml(const std::string& image_file, double resolution, const Eigen::Vector2d& origin,
                            const std::string& mode = "trinary");
// Encodes an 8-bit image (RGB, or grey) to PNG / PGM by the path's extension and writes it atomically.
void write_image_atomically(const std::filesystem::path& path, const cv::Mat& rgb_or_grey);

}  // namespace slamvdb
