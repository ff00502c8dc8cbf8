// slamvdb tokenize: the CLIP token ids of a text, exactly as a CLIP text encoder receives them.
#include <iostream>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "command_registry.hpp"
#include "option_checks.hpp"
#include "slamvdb/inference/clip_tokenizer.hpp"

namespace slamvdb::cli::cmd_tokenize {
namespace {

struct Options {
  std::string text, vocab;
  int context_length = ClipTokenizer::kContextLength;
  bool no_truncate = false, json = false;
};

void add(CLI::App& root) {
  auto opt = std::make_shared<Options>();
  auto* cmd = root.add_subcommand(
      "tokenize", "Print the CLIP token ids of a text: start token, BPE ids, end token, zero padding");
  cmd->add_option("text", opt->text, "Text to tokenize (UTF-8)")->required();
  cmd->add_option("--vocab", opt->vocab,
                  "CLIP BPE merge list bpe_simple_vocab_16e6.txt.gz (default: $SLAMVDB_CLIP_VOCAB, else "
                  "../shared/clip/ beside the source tree)");
  cmd->add_option("--context-length", opt->context_length, "Number of ids to print")
      ->check(integer_range(2, 1 << 20));
  cmd->add_flag("--no-truncate", opt->no_truncate, "Fail if the text does not fit, instead of truncating it");
  cmd->add_flag("--json", opt->json, "Print a JSON array instead of space-separated ids");
  cmd->callback([opt] {
    const ClipTokenizer tokenizer(opt->vocab.empty() ? default_clip_vocab_path()
                                                     : std::filesystem::path(opt->vocab));
    const std::vector<int64_t> ids = tokenizer.tokenize(opt->text, opt->context_length, !opt->no_truncate);
    if (opt->json) {
      std::cout << nlohmann::json(ids).dump() << '\n';
      return;
    }
    for (std::size_t i = 0; i < ids.size(); ++i) std::cout << (i ? " " : "") << ids[i];
    std::cout << '\n';
  });
}

const RegisterCommand reg{add};

}  // namespace
}  // namespace slamvdb::cli::cmd_tokenize
