// `slamvdb segment`: one camera image through the dense encoder; writes the feature map and the
// open-vocabulary segmentation it gives for a list of class names (best cosine per pixel).
#include <fmt/format.h>

#include <cstdio>
#include <memory>
#include <opencv2/imgproc.hpp>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/ontology.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/core/output_file.hpp"
#include "slamvdb/io/image_io.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/inference/torch_backend.hpp"
#include "slamvdb/io/image_codecs.hpp"

namespace slamvdb::cli::cmd_segment {
namespace {

namespace fs = std::filesystem;

struct Options {
  fs::path image, model, text_model, out_dir, labels;
  std::string classes;
  int threads = -1;
  bool simulated = false;
  double max_image_pixels = static_cast<double>(kDefaultMaxImagePixels);
};

struct Encoders {
  std::unique_ptr<DenseImageEncoder> dense;
  std::unique_ptr<TextEncoder> text;
};

Encoders make_encoders(const Options& opt) {
  if (opt.simulated) {
    if (opt.labels.empty()) throw Error("segment --simulated needs --labels (the image's 2D label PNG)");
    return {std::make_unique<SimulatedDenseEncoder>(), std::make_unique<SimulatedTextEncoder>()};
  }
  if (opt.model.empty() || opt.text_model.empty()) {
    throw Error("segment needs --model and --text-model (or --simulated with --labels)");
  }
  return {open_torch_dense_image_encoder(opt.model, TorchEncoderOptions{.threads = opt.threads}),
          open_torch_text_encoder(opt.text_model, TorchEncoderOptions{.threads = opt.threads})};
}

std::vector<std::string> parse_classes(const std::string& list) {
  std::vector<std::string> names;
  std::size_t start = 0;
  while (start <= list.size()) {
    const std::size_t end = std::min(list.find(',', start), list.size());
    std::string name = list.substr(start, end - start);
    name.erase(0, name.find_first_not_of(" \t"));
    name.erase(name.find_last_not_of(" \t") + 1);
    if (name.empty()) throw Error(fmt::format("--classes '{}' has an empty class name", list));
    // The names go into legend.txt (tab-separated) and onto the terminal: the rule of every class name.
    if (const std::string problem = display_name_problem(name); !problem.empty())
      throw Error(fmt::format("--classes: class name '{}' {}", escape_control(name, 80), problem));
    names.push_back(std::move(name));
    start = end + 1;
  }
  if (names.size() > 255)
    throw Error(fmt::format("--classes has {} names; at most 255 fit the label image", names.size()));
  return names;
}

// RELLIS-3D's colour for a RELLIS-3D class name, else well-separated hues.
cv::Vec3b class_colour(const std::string& name, std::size_t index) {
  if (const auto id = find_fine_class(name)) {
    const auto& rgb = find_fine_class(*id)->rgb;
    return {rgb[0], rgb[1], rgb[2]};
  }
  cv::Mat hsv(1, 1, CV_8UC3, cv::Scalar(static_cast<int>(index * 137.508) % 180, 200, 230)), rgb;
  cv::cvtColor(hsv, rgb, cv::COLOR_HSV2RGB);
  return rgb.at<cv::Vec3b>(0, 0);
}

// Index of the class whose embedding has the largest dot product with each pixel's.
cv::Mat best_class(const FeatureMap& features, const std::vector<std::vector<float>>& classes) {
  cv::Mat labels(features.height(), features.width(), CV_8UC1);
  std::vector<float> pixel(static_cast<std::size_t>(features.dim()));
  for (int y = 0; y < features.height(); ++y)
    for (int x = 0; x < features.width(); ++x) {
      features.decode_pixel(x, y, pixel.data());  // fp32 or a half-precision network's fp16
      const float* f = pixel.data();
      float best_score = -std::numeric_limits<float>::infinity();
      for (std::size_t k = 0; k < classes.size(); ++k) {
        float score = 0.0f;
        for (int c = 0; c < features.dim(); ++c) score += f[c] * classes[k][c];
        if (score > best_score) {
          best_score = score;
          labels.at<uint8_t>(y, x) = static_cast<uint8_t>(k);
        }
      }
    }
  return labels;
}

void write_png_atomically(const fs::path& path, const cv::Mat& image) {
  std::vector<uchar> png;
  if (!encode_image(".png", image, png)) throw Error(fmt::format("cannot encode {}", path.string()));
  write_output_file(path, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

void run(const Options& opt) {
  const std::vector<std::string> names = parse_classes(opt.classes);
  // Sized from the headers before decoding (a decompression bomb is refused), PNG or JPEG only.
  ImageRecord record;
  record.rgb = opt.image;
  record.labels = opt.labels;
  ImageFrame frame =
      load_image_frame(record, true, !opt.labels.empty(), static_cast<std::int64_t>(opt.max_image_pixels));
  frame.source = opt.image.string();

  const Encoders enc = make_encoders(opt);
  if (enc.dense->dim() != enc.text->dim()) {
    throw Error(fmt::format("image model '{}' gives {}-d features but text model '{}' gives {}-d embeddings",
                            enc.dense->model_id(), enc.dense->dim(), enc.text->model_id(), enc.text->dim()));
  }
  const FeatureMap features = enc.dense->encode(frame);
  std::vector<std::vector<float>> embeddings;
  for (const auto& name : names) embeddings.push_back(enc.text->encode(name));
  const cv::Mat labels = best_class(features, embeddings);

  fs::create_directories(opt.out_dir);
  write_feature_npy(opt.out_dir / "features.npy", features);
  std::vector<cv::Vec3b> colours;
  for (std::size_t k = 0; k < names.size(); ++k) colours.push_back(class_colour(names[k], k));
  cv::Mat colour(labels.size(), CV_8UC3);
  std::vector<std::size_t> counts(names.size(), 0);
  for (int y = 0; y < labels.rows; ++y)
    for (int x = 0; x < labels.cols; ++x) {
      const uint8_t k = labels.at<uint8_t>(y, x);
      ++counts[k];
      const cv::Vec3b& rgb = colours[k];
      colour.at<cv::Vec3b>(y, x) = {rgb[2], rgb[1], rgb[0]};  // imwrite wants BGR
    }
  write_png_atomically(opt.out_dir / "labels.png", labels);
  write_png_atomically(opt.out_dir / "classes.png", colour);
  std::string legend = "# index\tclass\tcolour\tpixels\tshare\n";
  const double total = static_cast<double>(labels.total());
  for (std::size_t k = 0; k < names.size(); ++k) {
    legend += fmt::format("{}\t{}\t#{:02x}{:02x}{:02x}\t{}\t{:.1f}%\n", k, names[k], colours[k][0], colours[k][1],
                          colours[k][2], counts[k], 100.0 * counts[k] / total);
  }
  write_output_file(opt.out_dir / "legend.txt", legend);
  // Model ids come from manifests, class names from the user: printed with control characters escaped.
  std::printf("%s: %d x %d x %d features (%s), best of %zu classes (%s) -> %s\n", escape_control(frame.source).c_str(),
              features.dim(), features.height(), features.width(), escape_control(enc.dense->model_id()).c_str(),
              names.size(), escape_control(enc.text->model_id()).c_str(), escape_control(opt.out_dir.string()).c_str());
  std::fputs(escape_control_keep_lines(legend).c_str(), stdout);
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "segment",
      "Run the dense image encoder (e.g. LSeg) on one image and segment it by a list of class names. Writes "
      "OUT_DIR/features.npy (C x H x W float32), labels.png (best class index per feature pixel), classes.png "
      "(the same in colour) and legend.txt (index, class, colour, pixel share). --simulated uses the SIMULATED "
      "encoders on the ground-truth labels instead of a network");
  cmd->add_option("image", opt->image, "Camera image (PNG / JPEG)")->required()->check(CLI::ExistingFile);
  auto* model = cmd->add_option("--model", opt->model, "Dense image encoder (.pt with its .json manifest beside it)");
  auto* text = cmd->add_option("--text-model", opt->text_model, "Text encoder for the class names (.pt with .json)");
  cmd->add_option("--classes", opt->classes, "Comma-separated class names, e.g. \"grass,tree,sky,dirt road\"")
      ->required();
  cmd->add_option("-o,--output,--out-dir", opt->out_dir, "Output directory (created if missing)")->required();
  cmd->add_option("--threads", opt->threads, "libtorch threads (default: the manifests' runtime.threads)")
      ->check(integer_range(-1, bounds::kMaxThreads));
  cmd->add_option("--max-image-pixels", opt->max_image_pixels,
                  "Refuse images larger than this (from their headers, before decoding)")
      ->capture_default_str()
      ->check(finite_range(1, bounds::kMaxImagePixels));
  auto* simulated = cmd->add_flag("--simulated", opt->simulated,
                                  "Use the SIMULATED encoders, which read the ground-truth --labels, not the image");
  simulated->excludes(model)->excludes(text);
  cmd->add_option("--labels", opt->labels, "2D label PNG of the image (RELLIS-3D ids), for --simulated")
      ->needs(simulated)
      ->check(CLI::ExistingFile);
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("image", opt->image);
  io->input("--model", opt->model);
  io->input("--text-model", opt->text_model);
  io->input("--labels", opt->labels);
  io->output_folder("-o", opt->out_dir, [](const std::string& dir) -> std::vector<fs::path> {
    return {fs::path(dir) / "features.npy", fs::path(dir) / "labels.png", fs::path(dir) / "classes.png",
            fs::path(dir) / "legend.txt"};
  });
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_segment
