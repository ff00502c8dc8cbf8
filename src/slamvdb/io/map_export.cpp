#include "slamvdb/io/map_export.hpp"

#include <sstream>

#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/map_pictures.hpp"
#include "slamvdb/io/npy.hpp"

#include <fmt/format.h>

#include <Eigen/Eigenvalues>
#include <algorithm>
#include <bit>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <tuple>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace fs = std::filesystem;
namespace {

static_assert(std::endian::native == std::endian::little, "binary PLY is written in host byte order");

// Value at quantile q of v (v is reordered).
float quantile(std::vector<float>& v, double q) {
  const auto k = static_cast<std::ptrdiff_t>(std::lround(q * static_cast<double>(v.size() - 1)));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<std::size_t>(k)];
}

uint8_t to_channel(float t) { return static_cast<uint8_t>(std::lround(std::clamp(t, 0.0f, 1.0f) * 255.0f)); }

}  // namespace

ColourBasis fit_pca_colouring(const SemanticMap& map, std::size_t max_samples) {
  const int dim = map.params().semantic.dim;
  Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor> X;
  map.read_index([&](const GlobalIndex& index) {
    if (index.size() == 0) throw Error("the map has no semantic voxels to fit a PCA colouring on");
    // An even subsample in key order: the same map always gets the same colours.
    const std::vector<std::size_t> order = index.order_by_key();
    const std::size_t samples = std::max<std::size_t>(max_samples, 1);
    const std::size_t stride = (order.size() + samples - 1) / samples;
    const auto m = static_cast<Eigen::Index>((order.size() + stride - 1) / stride);
    X.resize(m, dim);
    std::vector<float> scratch(static_cast<std::size_t>(dim));
    for (Eigen::Index i = 0; i < m; ++i) {
      const IndexedVoxel v = index.read(order[static_cast<std::size_t>(i) * stride], scratch.data());
      kernels::decode(v.embedding, X.row(i).data(), static_cast<std::size_t>(dim));
    }
  });
  const Eigen::Index m = X.rows();
  ColourBasis pca;
  pca.mean = X.colwise().mean().transpose();
  X.rowwise() -= pca.mean.transpose();
  const Eigen::MatrixXd covariance = (X.transpose() * X).cast<double>() / static_cast<double>(std::max<Eigen::Index>(m - 1, 1));
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(covariance);  // eigenvalues ascending
  pca.components.setZero(3, dim);
  for (int c = 0; c < std::min(3, dim); ++c) {
    Eigen::VectorXd axis = solver.eigenvectors().col(dim - 1 - c);
    Eigen::Index largest;
    axis.cwiseAbs().maxCoeff(&largest);
    if (axis[largest] < 0) axis = -axis;  // an eigenvector's sign is arbitrary; fix it for stable colours
    pca.components.row(c) = axis.cast<float>().transpose();
  }
  const Eigen::MatrixXf projections = X * pca.components.transpose();  // m x 3
  std::vector<float> values(static_cast<std::size_t>(m));
  for (int c = 0; c < 3; ++c) {
    Eigen::VectorXf::Map(values.data(), m) = projections.col(c);
    pca.lo[c] = quantile(values, 0.02);
    pca.hi[c] = quantile(values, 0.98);
  }
  return pca;
}

std::vector<ColouredVoxel> colour_occupied_voxels(const SemanticMap& map, const EmbeddingColour& semantic_colour) {
  // Occupied cells of the world occupancy and semantic cells of the index, merged in key order.
  const std::vector<WorldOccupancyCell> occupancy = map.world_occupancy();
  const float threshold = map.params().occupancy.occupied_threshold;
  std::vector<ColouredVoxel> voxels;
  std::vector<std::size_t> grey;  // voxels without semantics, coloured once the height range is known
  std::vector<float> scratch(static_cast<std::size_t>(map.params().semantic.dim));
  std::vector<float> embedding(scratch.size());
  map.read_index([&](const GlobalIndex& index) {
    const std::vector<std::size_t> order = index.order_by_key();
    voxels.reserve(occupancy.size() + order.size());
    const double cell = index.cell_size();
    std::size_t s = 0;
    auto add_semantic = [&](std::size_t i) {
      const IndexedVoxel v = index.read(i, scratch.data());
      kernels::decode(v.embedding, embedding.data(), embedding.size());
      voxels.push_back({v.position_world.cast<float>(), semantic_colour(embedding.data()), v.count});
    };
    for (const WorldOccupancyCell& c : occupancy) {
      while (s < order.size() && index.key(order[s]) < c.cell) add_semantic(order[s++]);
      if (s < order.size() && index.key(order[s]) == c.cell) {
        add_semantic(order[s++]);
      } else if (c.log_odds >= threshold) {
        grey.push_back(voxels.size());
        voxels.push_back({center_of_key(c.cell, cell).cast<float>(), {0, 0, 0}, 0});
      }
    }
    while (s < order.size()) add_semantic(order[s++]);
  });
  if (grey.empty()) return voxels;
  std::vector<float> heights(voxels.size());
  for (std::size_t i = 0; i < voxels.size(); ++i) heights[i] = voxels[i].position.z();
  const float z_lo = quantile(heights, 0.02), z_hi = quantile(heights, 0.98);
  for (const std::size_t i : grey) {
    const float t = z_hi > z_lo ? (voxels[i].position.z() - z_lo) / (z_hi - z_lo) : 0.5f;
    const auto g = static_cast<uint8_t>(60 + to_channel(t) * 180 / 255);  // 60..240: never black, never white
    voxels[i].rgb = {g, g, g};
  }
  return voxels;
}

ColourBasis colour_basis_of(const SemanticMap& map, const ColourBasis* chosen) {
  const int dim = map.params().semantic.dim;
  if (chosen) {
    chosen->validate(dim);
    return *chosen;
  }
  if (map.info().colour_basis) {
    map.info().colour_basis->validate(dim);
    return *map.info().colour_basis;
  }
  return fit_pca_colouring(map);
}

std::vector<ColouredVoxel> colour_by_pca(const SemanticMap& map, const ColourBasis* chosen) {
  if (map.num_index_cells() == 0) return colour_occupied_voxels(map, [](const float*) { return Rgb{}; });
  const ColourBasis pca = colour_basis_of(map, chosen);
  return colour_occupied_voxels(map, [&](const float* e) { return pca.colour(e); });
}

std::uint64_t write_ply(const fs::path& path, const std::vector<ColouredVoxel>& voxels, PlyEncoding encoding,
               const ExportProgress& progress) {
  OutputFile file(path);
  std::ostringstream out;
  const bool ascii = encoding == PlyEncoding::kAscii;
  out << "ply\nformat " << (ascii ? "ascii" : "binary_little_endian") << " 1.0\n"
      << "comment slamvdb map export: occupied voxel centres in the world frame, count = semantic observations\n"
      << "element vertex " << voxels.size() << "\n"
      << "property float x\nproperty float y\nproperty float z\n"
      << "property uchar red\nproperty uchar green\nproperty uchar blue\n"
      << "property int count\nend_header\n";
  std::uint64_t bytes = out.str().size();
  file.write(out.str());
  constexpr std::size_t kBatch = 65536;
  constexpr std::size_t kVertexBytes = 3 * sizeof(float) + 3 + sizeof(uint32_t);
  std::string buffer;
  for (std::size_t begin = 0; begin < voxels.size(); begin += kBatch) {
    const std::size_t end = std::min(voxels.size(), begin + kBatch);
    buffer.clear();
    for (std::size_t i = begin; i < end; ++i) {
      const ColouredVoxel& v = voxels[i];
      if (ascii) {
        fmt::format_to(std::back_inserter(buffer), "{} {} {} {} {} {} {}\n", v.position.x(), v.position.y(),
                       v.position.z(), v.rgb[0], v.rgb[1], v.rgb[2], std::min<uint32_t>(v.count, INT32_MAX));
      } else {
        char vertex[kVertexBytes];
        std::memcpy(vertex, v.position.data(), 3 * sizeof(float));
        std::memcpy(vertex + 12, v.rgb.data(), 3);
        const int32_t count = static_cast<int32_t>(std::min<uint32_t>(v.count, INT32_MAX));
        std::memcpy(vertex + 15, &count, sizeof(int32_t));
        buffer.append(vertex, kVertexBytes);
      }
    }
    file.write(buffer);
    bytes += buffer.size();
    if (progress) progress(end, voxels.size());
  }
  file.commit();
  return bytes;
}

void write_pcd_voxels(const fs::path& path, const std::vector<ColouredVoxel>& voxels) {
  const std::size_t n = voxels.size();
  std::string bytes = fmt::format(
      "# .PCD v0.7 - Point Cloud Data file format (slamvdb map export: occupied voxel centres, world frame)\n"
      "VERSION 0.7\nFIELDS x y z rgb count\nSIZE 4 4 4 4 4\nTYPE F F F U I\nCOUNT 1 1 1 1 1\nWIDTH {}\n"
      "HEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {}\nDATA binary\n",
      n, n);
  const std::size_t header = bytes.size();
  bytes.resize(header + n * 20);
  for (std::size_t i = 0; i < n; ++i) {
    const ColouredVoxel& v = voxels[i];
    char* p = bytes.data() + header + i * 20;
    const uint32_t rgb = uint32_t{v.rgb[0]} << 16 | uint32_t{v.rgb[1]} << 8 | v.rgb[2];
    const int32_t count = static_cast<int32_t>(std::min<uint32_t>(v.count, INT32_MAX));
    std::memcpy(p, v.position.data(), 12);
    std::memcpy(p + 12, &rgb, 4);
    std::memcpy(p + 16, &count, 4);
  }
  write_output_file(path, bytes);
}

std::size_t write_embeddings_npy(const fs::path& npy, const SemanticMap& map) {
  const auto dim = static_cast<std::size_t>(map.params().semantic.dim);
  std::vector<float> embeddings, positions, scratch(dim);
  std::vector<int32_t> counts;
  map.read_index([&](const GlobalIndex& index) {
    const std::vector<std::size_t> order = index.order_by_key();
    embeddings.resize(order.size() * dim);
    positions.reserve(order.size() * 3);
    counts.reserve(order.size());
    for (std::size_t r = 0; r < order.size(); ++r) {
      const IndexedVoxel v = index.read(order[r], scratch.data());
      kernels::decode(v.embedding, embeddings.data() + r * dim, dim);
      for (int k = 0; k < 3; ++k) positions.push_back(static_cast<float>(v.position_world[k]));
      counts.push_back(static_cast<int32_t>(std::min<uint32_t>(v.count, INT32_MAX)));
    }
  });
  const std::size_t n = counts.size();
  const std::vector<fs::path> files = embeddings_npy_files(npy);
  write_npy_array(files[0], embeddings.data(), {n, dim});
  write_npy_array(files[1], positions.data(), {n, 3});
  write_npy_array(files[2], counts.data(), {n}, NpyDtype::kInt32);
  return n;
}

std::vector<fs::path> embeddings_npy_files(const fs::path& npy) {
  fs::path base = npy;
  base.replace_extension();
  return {npy, base.string() + ".positions.npy", base.string() + ".counts.npy"};
}

Eigen::Vector2i BirdsEyeImage::pixel_of(double x, double y) const {
  const int col = static_cast<int>(std::floor((x - min_xy.x()) / resolution));
  const int row_from_bottom = static_cast<int>(std::floor((y - min_xy.y()) / resolution));
  return {col, rgb.rows - 1 - row_from_bottom};
}

BirdsEyeImage render_birds_eye(const std::vector<ColouredVoxel>& voxels, double voxel_size,
                               const BirdsEyeParams& params) {
  if (voxels.empty()) throw Error("the map has no occupied voxels to draw");
  if (!(voxel_size > 0)) throw Error(fmt::format("voxel size {} must be > 0", voxel_size));
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const ColouredVoxel& v : voxels) {
    lo = lo.cwiseMin(v.position.head<2>().cast<double>());
    hi = hi.cwiseMax(v.position.head<2>().cast<double>());
  }
  const double half = 0.5 * voxel_size;
  lo.array() -= half;
  hi.array() += half;
  const double extent = (hi - lo).maxCoeff();

  BirdsEyeImage image;
  image.min_xy = lo;
  if (params.resolution > 0) {
    image.resolution = params.resolution;
    if (extent / params.resolution > params.max_pixels)
      throw Error(fmt::format("a resolution of {} m per pixel makes the {:.0f} m wide map {:.0f} pixels wide, more "
                              "than {}; choose a coarser resolution",
                              params.resolution, extent, extent / params.resolution, params.max_pixels));
  } else {
    image.resolution = std::max(voxel_size, extent / params.max_auto_pixels);
  }
  const double res = image.resolution;
  const int width = std::max(1, static_cast<int>(std::ceil((hi.x() - lo.x()) / res - 1e-9)));
  const int height = std::max(1, static_cast<int>(std::ceil((hi.y() - lo.y()) / res - 1e-9)));

  // The pixels of one axis a voxel covers: those whose centres lie in its footprint, or the one
  // containing its centre when pixels are larger than voxels.
  const bool splat = res < voxel_size;
  auto pixel_range = [&](double centre, double origin, int size) {
    int first, last;
    if (splat) {
      first = static_cast<int>(std::ceil((centre - half - origin) / res - 0.5));
      last = static_cast<int>(std::ceil((centre + half - origin) / res - 0.5)) - 1;
    } else {
      first = last = static_cast<int>(std::floor((centre - origin) / res));
    }
    return std::make_pair(std::max(first, 0), std::min(last, size - 1));
  };

  // `top` holds the height of the voxel each pixel shows: the highest, or the lowest for kGround.
  const bool ground = params.layer == BirdsEyeParams::Layer::kGround;
  const float none = ground ? std::numeric_limits<float>::infinity() : -std::numeric_limits<float>::infinity();
  std::vector<float> top(static_cast<std::size_t>(width) * height, none);
  image.rgb = cv::Mat(height, width, CV_8UC3, cv::Scalar(params.background[0], params.background[1], params.background[2]));
  for (const ColouredVoxel& v : voxels) {
    const auto [c0, c1] = pixel_range(v.position.x(), lo.x(), width);
    const auto [r0, r1] = pixel_range(v.position.y(), lo.y(), height);
    for (int r = r0; r <= r1; ++r)
      for (int c = c0; c <= c1; ++c) {
        const int row = height - 1 - r;
        float& z = top[static_cast<std::size_t>(row) * width + c];
        if (ground ? v.position.z() >= z : v.position.z() <= z) continue;
        z = v.position.z();
        image.rgb.at<cv::Vec3b>(row, c) = {v.rgb[0], v.rgb[1], v.rgb[2]};
      }
  }

  if (params.hill_shading) {
    // Lambertian relief from the north-west, 45 degrees up, normalised so flat ground keeps its colour.
    const Eigen::Vector3d light = Eigen::Vector3d(-1.0, 1.0, std::sqrt(2.0)).normalized();
    auto height_at = [&](int row, int col, float fallback) {
      if (row < 0 || row >= height || col < 0 || col >= width) return fallback;
      const float z = top[static_cast<std::size_t>(row) * width + col];
      return std::isfinite(z) ? z : fallback;
    };
    for (int row = 0; row < height; ++row)
      for (int col = 0; col < width; ++col) {
        const float z = top[static_cast<std::size_t>(row) * width + col];
        if (!std::isfinite(z)) continue;
        const double dzdx = (height_at(row, col + 1, z) - height_at(row, col - 1, z)) / (2 * res);
        const double dzdy = (height_at(row - 1, col, z) - height_at(row + 1, col, z)) / (2 * res);  // rows go south
        const double shade = Eigen::Vector3d(-dzdx, -dzdy, 1.0).normalized().dot(light) / light.z();
        const double factor = std::clamp(0.5 + 0.5 * shade, 0.5, 1.3);
        cv::Vec3b& p = image.rgb.at<cv::Vec3b>(row, col);
        for (int ch = 0; ch < 3; ++ch) p[ch] = cv::saturate_cast<uint8_t>(p[ch] * factor);
      }
  }
  return image;
}

void write_png(const fs::path& path, const BirdsEyeImage& image) {
  std::string extension = path.extension().string();
  std::transform(extension.begin(), extension.end(), extension.begin(), [](unsigned char c) { return std::tolower(c); });
  if (extension != ".png") throw Error(fmt::format("bird's-eye image {} must have the extension .png", path.string()));
  write_image_atomically(path, image.rgb);
}

}  // namespace slamvdb
