#pragma once
// The accuracy-coverage curve as a plot (eval --coverage-png, the demo's coverage.png): the voxel
// accuracy of the most confident x of the voxels against x, one line per named curve (e.g. the
// paper's fusion rule and quality weighting), with axes, grid, labels and a legend.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "slamvdb/eval/map_evaluation.hpp"

namespace slamvdb {

struct NamedCoverage {
  std::string name;
  std::vector<CoveragePoint> curve;  // by increasing fraction
};

// The fractions the plot samples: 0.05, 0.10, .., 1.
std::vector<double> coverage_plot_fractions();

// RGB image. Throws Error without a curve or with an empty one.
cv::Mat render_coverage_plot(const std::vector<NamedCoverage>& curves, const std::string& title = {});
// Written atomically; throws Error naming the file if it cannot be written.
void write_coverage_png(const std::filesystem::path& file, const std::vector<NamedCoverage>& curves,
                        const std::string& title = {});

}  // namespace slamvdb
