// The `slamvdb` Python module (pybind11): load, build, query and save semantic maps from Python with
// numpy arrays. A thin adapter: every call goes to the C++ library.
#include <limits>
#include <pybind11/eigen.h>
#include <pybind11/functional.h>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>
#include <pybind11/stl/filesystem.h>

#include "slamvdb/core/error.hpp"
#include "slamvdb/fusion/projective_fusion.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/query/map_query.hpp"
#include "slamvdb/store/map_store.hpp"
#if SLAMVDB_WITH_TORCH
#include "slamvdb/inference/torch_encoders.hpp"
#endif

namespace py = pybind11;
using namespace slamvdb;

namespace {

using F32 = py::array_t<float, py::array::c_style | py::array::forcecast>;
using F64 = py::array_t<double, py::array::c_style | py::array::forcecast>;

Pose pose_from(const F64& m) {
  if (m.ndim() != 2 || m.shape(0) != 4 || m.shape(1) != 4) throw Error("a pose is a 4 x 4 matrix");
  Pose T;
  for (int r = 0; r < 4; ++r)
    for (int c = 0; c < 4; ++c) T.matrix()(r, c) = m.at(r, c);
  return T;
}

std::vector<Vec3f> points_from(const F32& a) {
  if (a.ndim() != 2 || a.shape(1) < 3) throw Error("points are an N x 3 (or N x 4) array");
  std::vector<Vec3f> pts(static_cast<std::size_t>(a.shape(0)));
  const auto r = a.unchecked<2>();
  for (py::ssize_t i = 0; i < a.shape(0); ++i) pts[i] = Vec3f(r(i, 0), r(i, 1), r(i, 2));
  return pts;
}

// Semantic cells of the map's global index in cell order: positions, embeddings, counts.
py::tuple semantic_voxels(const SemanticMap& map) {
  const auto dim = static_cast<py::ssize_t>(map.params().semantic.dim);
  py::array_t<double> positions;
  py::array_t<float> embeddings;
  py::array_t<uint32_t> counts;
  map.read_index([&](const GlobalIndex& index) {
    const std::vector<std::size_t> order = index.order_by_key();
    const auto n = static_cast<py::ssize_t>(order.size());
    positions = py::array_t<double>({n, py::ssize_t{3}});
    embeddings = py::array_t<float>({n, dim});
    counts = py::array_t<uint32_t>(n);
    auto p = positions.mutable_unchecked<2>();
    auto c = counts.mutable_unchecked<1>();
    float* e = embeddings.mutable_data();
    std::vector<float> scratch(static_cast<std::size_t>(dim));
    for (py::ssize_t i = 0; i < n; ++i) {
      const IndexedVoxel v = index.read(order[static_cast<std::size_t>(i)], scratch.data());
      for (int k = 0; k < 3; ++k) p(i, k) = v.position_world[k];
      c(i) = v.count;
      kernels::decode(v.embedding, e + i * dim, static_cast<std::size_t>(dim));
    }
  });
  return py::make_tuple(positions, embeddings, counts);
}

// A cell's spread as the API reports it: S / W (the weighted mean squared distance of its
// observations from their mean), NaN when not known (map files before format 3).
float spread_per_weight(VoxelStatistics s) {
  return s.known() && s.weight > 0 ? s.spread / s.weight : std::numeric_limits<float>::quiet_NaN();
}

// The statistics of the semantic cells, in the order of semantic_voxels (not a wider tuple there:
// callers unpack it).
py::tuple statistics(const SemanticMap& map) {
  py::array_t<float> weights, spreads;
  map.read_index([&](const GlobalIndex& index) {
    const std::vector<std::size_t> order = index.order_by_key();
    const auto n = static_cast<py::ssize_t>(order.size());
    weights = py::array_t<float>(n);
    spreads = py::array_t<float>(n);
    std::vector<float> scratch(static_cast<std::size_t>(map.params().semantic.dim));
    for (py::ssize_t i = 0; i < n; ++i) {
      const std::size_t cell = order[static_cast<std::size_t>(i)];
      index.read(cell, scratch.data());  // the mean of a shared cell, which its statistics need
      const VoxelStatistics st = index.statistics(cell, scratch.data());
      weights.mutable_at(i) = st.weight;
      spreads.mutable_at(i) = spread_per_weight(st);
    }
  });
  return py::make_tuple(weights, spreads);
}

py::tuple search(const SemanticMap& map, const F32& query, std::size_t top_k, std::optional<float> threshold) {
  SearchOptions o;
  o.top_k = top_k;
  if (threshold) o.threshold = *threshold;
  const auto found = similarity_search(map, {query.data(), static_cast<std::size_t>(query.size())}, o);
  const auto n = static_cast<py::ssize_t>(found.size());
  py::array_t<double> positions({n, py::ssize_t{3}});
  py::array_t<float> scores(n);
  py::array_t<uint32_t> counts(n);
  auto p = positions.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) p(i, k) = found[i].position_world[k];
    scores.mutable_at(i) = found[i].score;
    counts.mutable_at(i) = found[i].count;
  }
  return py::make_tuple(positions, scores, counts);
}

// search with what the map knows of each result: weights, spreads (S/W), and with a query set the
// class (-1: none) and its confidence, as classify and at give them.
py::dict search_details(const SemanticMap& map, const F32& query, std::size_t top_k, std::optional<float> threshold,
                        const QuerySet* queries, bool void_rule, bool ignore_model_id) {
  SearchOptions o;
  o.top_k = top_k;
  if (threshold) o.threshold = *threshold;
  auto found = similarity_search(map, {query.data(), static_cast<std::size_t>(query.size())}, o);
  if (queries) {
    ClassifyOptions c;
    c.void_to_second_best = void_rule;
    classify_results(map, *queries, found, c, ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch);
  }
  const auto n = static_cast<py::ssize_t>(found.size());
  py::array_t<double> positions({n, py::ssize_t{3}});
  py::array_t<float> scores(n), weights(n), spreads(n), confidences(n);
  py::array_t<uint32_t> counts(n);
  py::array_t<int32_t> classes(n);
  auto p = positions.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    const ScoredCell& r = found[static_cast<std::size_t>(i)];
    for (int k = 0; k < 3; ++k) p(i, k) = r.position_world[k];
    scores.mutable_at(i) = r.score;
    counts.mutable_at(i) = r.count;
    weights.mutable_at(i) = r.stats.weight;
    spreads.mutable_at(i) = spread_per_weight(r.stats);
    classes.mutable_at(i) = r.match ? r.match->class_index : kNoClass;
    confidences.mutable_at(i) = r.confidence;
  }
  py::dict d;
  d["positions"] = positions, d["scores"] = scores, d["counts"] = counts, d["weights"] = weights, d["spreads"] = spreads;
  if (queries) d["classes"] = classes, d["confidences"] = confidences, d["names"] = queries->names;
  return d;
}

py::dict classify(const SemanticMap& map, const QuerySet& queries, bool void_rule, bool ignore_model_id) {
  ClassifyOptions o;
  o.void_to_second_best = void_rule;
  std::vector<ClassifiedCell> cells =
      classify_map(map, queries, o, ignore_model_id ? ModelIdCheck::kIgnore : ModelIdCheck::kRequireMatch);
  sort_by_cell(cells);
  const auto n = static_cast<py::ssize_t>(cells.size());
  py::array_t<double> positions({n, py::ssize_t{3}});
  py::array_t<int32_t> classes(n);
  py::array_t<float> scores(n), margins(n), confidences(n);
  py::array_t<uint32_t> counts(n);
  auto p = positions.mutable_unchecked<2>();
  for (py::ssize_t i = 0; i < n; ++i) {
    for (int k = 0; k < 3; ++k) p(i, k) = cells[i].position_world[k];
    classes.mutable_at(i) = cells[i].match.class_index;
    scores.mutable_at(i) = cells[i].match.score;
    margins.mutable_at(i) = cells[i].match.margin;
    confidences.mutable_at(i) = cells[i].confidence;
    counts.mutable_at(i) = cells[i].count;
  }
  py::dict d;
  d["positions"] = positions, d["classes"] = classes, d["scores"] = scores, d["margins"] = margins;
  d["confidences"] = confidences;
  d["counts"] = counts, d["names"] = queries.names;
  return d;
}

py::dict at_points(const SemanticMap& map, const F64& points) {
  if (points.ndim() != 2 || points.shape(1) != 3) throw Error("points are an N x 3 array");
  std::vector<Vec3d> pts(static_cast<std::size_t>(points.shape(0)));
  const auto r = points.unchecked<2>();
  for (py::ssize_t i = 0; i < points.shape(0); ++i) pts[i] = Vec3d(r(i, 0), r(i, 1), r(i, 2));
  const auto answers = query_points(map, pts);
  const auto n = static_cast<py::ssize_t>(answers.size()), dim = static_cast<py::ssize_t>(map.params().semantic.dim);
  py::array_t<bool> found(n);
  py::array_t<uint32_t> counts(n);
  py::array_t<float> embeddings({n, dim}), weights(n), spreads(n);
  float* e = embeddings.mutable_data();
  for (py::ssize_t i = 0; i < n; ++i) {
    found.mutable_at(i) = answers[i].found;
    counts.mutable_at(i) = answers[i].count;
    weights.mutable_at(i) = answers[i].found ? answers[i].stats.weight : 0.0f;
    spreads.mutable_at(i) = answers[i].found ? spread_per_weight(answers[i].stats) : std::numeric_limits<float>::quiet_NaN();
    for (py::ssize_t k = 0; k < dim; ++k) e[i * dim + k] = answers[i].found ? answers[i].embedding[k] : 0.0f;
  }
  py::dict d;
  d["found"] = found, d["counts"] = counts, d["embeddings"] = embeddings, d["weights"] = weights, d["spreads"] = spreads;
  return d;
}

// Fuses an H x W x C feature map (pixel-major, as the encoders produce) seen by a pinhole camera.
// float16 arrays stay fp16 (fusion reads them directly, as from a half-precision network); any
// other dtype is converted to float32.
py::dict fuse_features(SemanticMap& map, double stamp, const py::array& features, const py::dict& camera,
                       const F64& T_world_camera) {
  if (features.ndim() != 3) throw Error("features are an H x W x C array");
  const int dim = static_cast<int>(features.shape(2)), height = static_cast<int>(features.shape(0)),
            width = static_cast<int>(features.shape(1));
  FeatureMap f;
  if (features.dtype().is(py::dtype("float16"))) {
    using Bits = py::array_t<uint16_t, py::array::c_style | py::array::forcecast>;
    const Bits bits = Bits::ensure(features.attr("view")("uint16"));  // the same bits, contiguous
    f.reset(dim, height, width, EmbeddingPrecision::kFloat16);
    std::copy_n(bits.data(), f.size(), f.half_values().begin());
  } else {
    const F32 values = F32::ensure(features);
    if (!values) throw Error("features: expected a float array");
    f.reset(dim, height, width);
    std::copy_n(values.data(), f.size(), f.values().begin());
  }
  CameraModel cam;
  cam.width = f.width(), cam.height = f.height();
  cam.fx = camera["fx"].cast<double>(), cam.fy = camera["fy"].cast<double>();
  cam.cx = camera["cx"].cast<double>(), cam.cy = camera["cy"].cast<double>();
  const Pose T = pose_from(T_world_camera);
  // The rule the map records (a new map: the default one, as its info says; a loaded map: the rule
  // it was made with), so that the map's metadata stays true.
  FusionParams params;
  params.weighting = fusion_weighting_from_string(map.info().fusion);
  ProjectiveFusion fusion(params);
  FusionStats stats;
  const bool active = map.update_active(stamp, [&](VoxelMap& v, const Pose& T_world_submap, std::span<const PlacedVoxelMap>) {
    stats = fusion.fuse(v, f, cam, T_world_submap.inverse() * T, {}, T_world_submap);
  });
  py::dict d;
  d["fused"] = active, d["voxels"] = stats.fused_voxels, d["pixels_used"] = stats.pixels_used;
  d["pixels_nonfinite"] = stats.pixels_nonfinite, d["pixels_zero"] = stats.pixels_zero;
  d["feature_precision"] = f.precision() == EmbeddingPrecision::kFloat16 ? "fp16" : "fp32";  // as fused
  return d;
}

}  // namespace

PYBIND11_MODULE(slamvdb, m) {
  m.doc() = "slamvdb: open-vocabulary semantic voxel maps (Python API over the C++ library).\n\n"
            "Arrays are numpy arrays; positions are in the world frame (metres); poses are 4 x 4 "
            "T_world_sensor / T_world_camera matrices.";
  py::register_exception<Error>(m, "Error").doc() =
      "A slamvdb error: a bad or unreadable file, a bad argument (the message names it)";

  py::class_<SemanticMap>(m, "Map",
                          "A semantic voxel map: free-floating submaps read through a global index (world frame)")
      .def(py::init([](double voxel_size, int dim, const std::string& precision, double submap_length,
                       const std::string& model_id) {
             MapParams p;
             p.occupancy.voxel_size = voxel_size;
             p.semantic = {dim, precision_from_string(precision)};
             p.submap_length = submap_length;
             return std::make_unique<SemanticMap>(p, map_info_for("python", model_id, model_id, FusionParams{}));
           }),
           py::arg("voxel_size") = 0.25, py::arg("dim") = 512, py::arg("precision") = "fp16",
           py::arg("submap_length") = 50.0, py::arg("model_id") = "",
           "An empty map: voxel edge (m), embedding dimension, storage precision ('fp16' or 'fp32'), metres of "
           "path per submap (0: one submap), and the id of the encoder whose embedding space it holds")
      .def_property_readonly("voxel_size", [](const SemanticMap& s) { return s.params().occupancy.voxel_size; },
                             "Voxel edge in metres")
      .def_property_readonly("dim", [](const SemanticMap& s) { return s.params().semantic.dim; },
                             "Embedding dimension")
      .def_property_readonly("model_id", [](const SemanticMap& s) { return s.info().model_id; },
                             "The encoder whose embedding space the map holds")
      .def_property_readonly("num_submaps", &SemanticMap::num_submaps, "Submaps in the map")
      .def_property_readonly("num_semantic_voxels", &SemanticMap::num_index_cells,
                             "Semantic cells of the global index (world frame)")
      .def("integrate_scan",
           [](SemanticMap& s, double stamp, const F32& points, const F64& T_world_sensor) {
             const auto st = s.integrate_scan(stamp, points_from(points), pose_from(T_world_sensor));
             return py::dict(py::arg("points") = st.points, py::arg("dropped") = st.dropped(),
                             py::arg("hits") = st.hit_updates, py::arg("misses") = st.miss_updates);
           },
           py::arg("stamp"), py::arg("points"), py::arg("T_world_sensor"),
           "Integrate one LiDAR scan (N x 3 points in the sensor frame) at a pose; returns counts: points, "
           "dropped, hits, misses")
      .def("fuse_features", &fuse_features, py::arg("stamp"), py::arg("features"), py::arg("camera"),
           py::arg("T_world_camera"),
           "Fuse an H x W x C feature map with the fusion rule the map records ('paper' for a new map); camera = "
           "{'fx', 'fy', 'cx', 'cy'} at the feature resolution")
      .def("finish", &SemanticMap::finish_active_submap, "Store the submap being written (call before saving)")
      .def("save", [](const SemanticMap& s, const std::filesystem::path& p) { save_map(p, s); }, py::arg("path"),
           "Write the map file (.svdb), atomically")
      .def("semantic_voxels", &semantic_voxels, "(positions N x 3, embeddings N x dim, counts N), in cell order")
      .def("statistics", &statistics,
           "(weights N, spreads N) of the semantic voxels, in the order of semantic_voxels: the observations' summed "
           "weight (the count under the paper's rule) and their spread S/W (weighted mean squared distance from the "
           "voxel's embedding; NaN for maps saved before format 3)")
      .def("occupied_voxels",
           [](const SemanticMap& s) {
             std::vector<double> xyz;
             const float threshold = s.params().occupancy.occupied_threshold;
             const double cell = s.params().index_cell();
             for (const WorldOccupancyCell& c : s.world_occupancy())
               if (c.log_odds >= threshold)
                 for (int k = 0; k < 3; ++k) xyz.push_back((c.cell[k] + 0.5) * cell);
             py::array_t<double> a({static_cast<py::ssize_t>(xyz.size() / 3), py::ssize_t{3}});
             std::copy(xyz.begin(), xyz.end(), a.mutable_data());
             return a;
           },
           "Centres of the occupied world cells (all submaps combined), N x 3")
      .def("search", &search, py::arg("query"), py::arg("top_k") = 100, py::arg("threshold") = py::none(),
           "Cosine similarity with a query vector: (positions, scores, counts), best first")
      .def("search_details", &search_details, py::arg("query"), py::arg("top_k") = 100,
           py::arg("threshold") = py::none(), py::arg("queries") = nullptr, py::arg("void_rule") = true,
           py::arg("ignore_model_id") = false,
           "search with what the map knows of each result, best first: dict of positions, scores, counts, weights, "
           "spreads (S/W; NaN where not known), and with queries also classes (-1: none), confidences (as classify "
           "gives them), names")
      .def("classify", &classify, py::arg("queries"), py::arg("void_rule") = true, py::arg("ignore_model_id") = false,
           "Label every semantic voxel with its most similar query (void takes its second-best with void_rule): "
           "dict of positions, classes, scores, margins, confidences (0..1: class margin x n/(n+2) for n views, as "
           "classify --min-confidence uses), counts, names")
      .def("at", &at_points, py::arg("points"),
           "What the map holds at world points (N x 3): dict of found, counts, embeddings, weights, spreads (S/W; NaN "
           "where not found or not known)");

  m.def("load_map", [](const std::filesystem::path& p) { return std::make_unique<SemanticMap>(load_map(p)); },
        py::arg("path"), "Load a map file (.svdb)");

  py::class_<QuerySet>(m, "QuerySet", "Named query vectors in one embedding space")
      .def_static("load", &load_query_set, py::arg("path"),
                  "Load a query set file (.json, from train-queries or import-queries)")
      .def_readonly("names", &QuerySet::names, "Class names, in order")
      .def_readonly("model_id", &QuerySet::model_id, "The encoder whose embedding space the vectors are in")
      .def_property_readonly("vectors", [](const QuerySet& q) { return Eigen::MatrixXf(q.vectors); },
                             "One query vector per class: classes x dim");

  m.def("composite_query",
        [](const std::vector<Eigen::VectorXf>& positive, const std::vector<Eigen::VectorXf>& negative) {
          return composite_query(positive, negative);
        },
        py::arg("positive"), py::arg("negative") = std::vector<Eigen::VectorXf>{},
        "sum(positive) - sum(negative), each term normalised, normalised (paper Figure 6.2)");
  m.def("simulated_text_embedding",
        [](const std::string& text, int dim, uint64_t seed) {
          SimulatedEncoderConfig c;
          c.dim = dim, c.seed = seed;
          const auto v = SimulatedTextEncoder(c).encode(text);
          return Eigen::VectorXf(Eigen::Map<const Eigen::VectorXf>(v.data(), static_cast<Eigen::Index>(v.size())));
        },
        py::arg("text"), py::arg("dim") = 512, py::arg("seed") = 1,
        "Text embedding from the SIMULATED text encoder (the space of maps built with simulated features)");
#if SLAMVDB_WITH_TORCH
  py::class_<TorchTextEncoder>(m, "TextEncoder", "A TorchScript CLIP text encoder (MODEL.pt with MODEL.json)")
      .def(py::init([](const std::filesystem::path& p) { return std::make_unique<TorchTextEncoder>(p); }),
           py::arg("path"), "Load MODEL.pt (its manifest MODEL.json beside it)")
      .def_property_readonly("model_id", &TorchTextEncoder::model_id, "The model's embedding space")
      .def(
          "encode",
          [](TorchTextEncoder& e, const std::string& t) {
            const auto v = e.encode(t);
            return Eigen::VectorXf(Eigen::Map<const Eigen::VectorXf>(v.data(), static_cast<Eigen::Index>(v.size())));
          },
          py::arg("text"), "The text's embedding (dim)");
#endif
}
