#pragma once
// Views of a SemanticMap for people: a coloured PLY point cloud and a bird's-eye PNG. Colours are
// decided per voxel first (PCA of the embeddings here; a class colouring can supply its own) and
// the writers only take coloured voxels.
#include <Eigen/Core>
#include <array>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

#include "slamvdb/map/colour_basis.hpp"
#include "slamvdb/map/semantic_map.hpp"

namespace slamvdb {

using Rgb = Rgb8;

// One occupied voxel in the world frame.
struct ColouredVoxel {
  Vec3f position;  // voxel centre, world frame
  Rgb rgb;
  uint32_t count;  // semantic observation count, 0 without semantics
};

// The first three principal components of the map's embeddings as a colour basis, their 2nd and
// 98th percentiles as channels 0 and 255. Fits on at most `max_samples` semantic voxels, an even
// subsample in key order (the same map always gets the same basis). Throws Error when the map has
// no semantic voxels.
ColourBasis fit_pca_colouring(const SemanticMap& map, std::size_t max_samples = 20000);

// The basis a map is drawn in: `chosen` if given, else the one saved in the map
// (MapInfo::colour_basis), else one fitted on the map (maps saved before bases were recorded).
ColourBasis colour_basis_of(const SemanticMap& map, const ColourBasis* chosen = nullptr);

// Colour of a semantic voxel from its decoded embedding (map.params.semantic.dim floats).
using EmbeddingColour = std::function<Rgb(const float* embedding)>;

// Every occupied voxel of every submap, placed by its submap pose. Semantic voxels get
// `semantic_colour`; the others a grey by world height (2nd..98th percentile: dark..light).
std::vector<ColouredVoxel> colour_occupied_voxels(const SemanticMap& map, const EmbeddingColour& semantic_colour);
// The same with PCA colours for semantic voxels, in colour_basis_of(map, chosen).
std::vector<ColouredVoxel> colour_by_pca(const SemanticMap& map, const ColourBasis* chosen = nullptr);

using ExportProgress = std::function<void(std::size_t done, std::size_t total)>;

enum class PlyEncoding { kBinaryLittleEndian, kAscii };
// One vertex per voxel: float x y z, uchar red green blue, int count (int32: Open3D's tensor reader
// drops unsigned properties), written atomically (core/output_file.hpp). Returns the bytes written;
// throws Error on I/O failure.
std::uint64_t write_ply(const std::filesystem::path& path, const std::vector<ColouredVoxel>& voxels, PlyEncoding encoding,
               const ExportProgress& progress = {});

// The same voxels as a PCL point cloud: binary PCD v0.7, FIELDS x y z rgb count (rgb packed as
// PCL does, 0x00RRGGBB in a U4; count I4), written atomically.
void write_pcd_voxels(const std::filesystem::path& path, const std::vector<ColouredVoxel>& voxels);

// The semantic voxels of the global index for other tools: PREFIX.npy (N x dim float32
// embeddings, decoded), PREFIX.positions.npy (N x 3 float32 world cell centres),
// PREFIX.counts.npy (N int32), rows in key order. Returns N.
std::size_t write_embeddings_npy(const std::filesystem::path& npy, const SemanticMap& map);
// The three files write_embeddings_npy writes for `npy`.
std::vector<std::filesystem::path> embeddings_npy_files(const std::filesystem::path& npy);

struct BirdsEyeParams {
  double resolution = 0.0;    // metres per pixel; 0: the voxel size, coarser if needed for max_auto_pixels
  int max_auto_pixels = 2000;  // longest side when the resolution is automatic
  int max_pixels = 20000;     // longest side allowed for an explicit resolution
  bool hill_shading = false;  // light relief shading from the north-west
  // Which voxel of a column a pixel shows: the highest (what a camera above sees: tree crowns),
  // or the lowest (the terrain under them).
  enum class Layer { kTop, kGround } layer = Layer::kTop;
  Rgb background = {0, 0, 0};
};

// Top-down orthographic view, world x to the right and y up; a pixel shows the highest (or, with
// Layer::kGround, the lowest) voxel whose footprint covers its centre (or, when pixels are larger
// than voxels, whose centre it contains).
struct BirdsEyeImage {
  cv::Mat rgb;                  // CV_8UC3 in RGB order
  double resolution = 0.0;      // metres per pixel
  Eigen::Vector2d min_xy{0, 0};  // world x of the left edge, y of the bottom edge
  // (column, row) of the pixel containing world point (x, y).
  Eigen::Vector2i pixel_of(double x, double y) const;
};

BirdsEyeImage render_birds_eye(const std::vector<ColouredVoxel>& voxels, double voxel_size,
                               const BirdsEyeParams& params = {});
void write_png(const std::filesystem::path& path, const BirdsEyeImage& image);  // atomically; throws Error

}  // namespace slamvdb
