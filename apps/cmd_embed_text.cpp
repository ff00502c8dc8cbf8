// `slamvdb embed-text`: one text -> its embedding, printed as one CSV line (the format of the
// shipped query-vector files), as JSON, or saved as a float32 .npy.
#include <fmt/format.h>

#include <cstdio>
#include <memory>
#include <nlohmann/json.hpp>

#include "command_registry.hpp"
#include "io_options.hpp"
#include "option_checks.hpp"
#include "slamvdb/core/error.hpp"
#include "slamvdb/core/text_escape.hpp"
#include "slamvdb/inference/simulated_encoders.hpp"
#include "slamvdb/io/npy.hpp"
#include "slamvdb/inference/torch_backend.hpp"

namespace slamvdb::cli::cmd_embed_text {
namespace {

namespace fs = std::filesystem;

struct Options {
  std::string text;
  fs::path model, out;
  bool json = false, simulated = false;
  int threads = -1;
};

std::unique_ptr<TextEncoder> make_encoder(const Options& opt) {
  if (opt.simulated) return std::make_unique<SimulatedTextEncoder>();
  if (opt.model.empty()) throw Error("embed-text needs --model TEXT_MODEL.pt (or --simulated)");
  return open_torch_text_encoder(opt.model, TorchEncoderOptions{.threads = opt.threads});
}

void run(const Options& opt) {
  const auto encoder = make_encoder(opt);
  const std::vector<float> v = encoder->encode(opt.text);
  if (!opt.out.empty()) {
    write_npy_array(opt.out, v.data(), {v.size()});
    std::fprintf(stderr, "wrote %zu-d embedding of \"%s\" (%s) to %s\n", v.size(), escape_control(opt.text).c_str(),
                 escape_control(encoder->model_id()).c_str(), escape_control(opt.out.string()).c_str());
    return;
  }
  if (opt.json) {
    const nlohmann::json j = {
        {"model_id", encoder->model_id()}, {"text", opt.text}, {"dim", v.size()}, {"embedding", v}};
    // ASCII only (\uXXXX escapes): a model id from a manifest cannot carry terminal controls.
    std::printf("%s\n", j.dump(-1, ' ', true, nlohmann::json::error_handler_t::replace).c_str());
  } else {
    std::printf("%s\n", fmt::format("{:.9g}", fmt::join(v, ",")).c_str());
  }
}

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "embed-text",
      "Embed a text with a CLIP-style text encoder (TorchScript MODEL.pt with its MODEL.json manifest beside it) "
      "and print the vector as one CSV line, as JSON, or save it as .npy");
  cmd->add_option("text", opt->text, "The text to embed, e.g. \"tall grass\"")->required();
  auto* model = cmd->add_option("--model", opt->model, "Text encoder model (.pt, or its .json manifest)");
  cmd->add_option("-o,--output,--out", opt->out, "Write the vector as a float32 .npy of shape (dim,) instead of printing it");
  cmd->add_flag("--json", opt->json, "Print {model_id, text, dim, embedding} as JSON instead of a CSV line");
  cmd->add_option("--threads", opt->threads, "libtorch threads (default: the manifest's runtime.threads)")
      ->check(integer_range(-1, bounds::kMaxThreads));
  cmd->add_flag("--simulated", opt->simulated, "Use the SIMULATED text encoder (for synthetic data only)")
      ->excludes(model);
  auto io = std::make_shared<IoOptions>(cmd);
  io->input("--model", opt->model);
  io->output("-o", opt->out);
  cmd->callback([opt, io] {
    io->check();
    run(*opt);
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_embed_text
