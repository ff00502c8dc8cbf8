#pragma once
// OpenAI CLIP's text tokenizer (clip/simple_tokenizer.py and clip.tokenize), re-implemented:
// the clean-up of clip_text_clean.hpp, the pre-tokenisation regex
//   <\|startoftext\|>|<\|endoftext\|>|'s|'t|'re|'ve|'m|'ll|'d|[\p{L}]+|[\p{N}]|[^\s\p{L}\p{N}]+
// (IGNORECASE), then byte-level BPE over the merge list bpe_simple_vocab_16e6.txt.gz with '</w>'
// marking the end of a word. Vocabulary: 256 byte symbols, the same with '</w>', 48 894 merges,
// <|startoftext|>, <|endoftext|> (49 408 ids). Ids match CLIP's for ordinary text; the one part of
// CLIP's clean-up not reproduced is ftfy's mojibake repair (see clip_text_clean.hpp).
#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

namespace slamvdb {

class ClipTokenizer {
 public:
  static constexpr int kContextLength = 77, kStartToken = 49406, kEndToken = 49407;

  // Reads the gzip-compressed merge list; throws Error if it is missing, not gzip or malformed.
  explicit ClipTokenizer(const std::filesystem::path& merges_gz);

  // BPE ids of the text, without start/end tokens. Throws Error if the text is not valid UTF-8.
  std::vector<int> encode(std::string_view utf8_text) const;

  // start + ids + end, zero-padded to context_length. If too long and `truncate`: the first
  // context_length - 1 tokens and the end token last (clip.tokenize(truncate=True)); else Error.
  std::vector<int64_t> tokenize(std::string_view utf8_text, int context_length = kContextLength,
                                bool truncate = true) const;

  // The text of the ids as CLIP decodes it: bytes joined, invalid UTF-8 replaced by U+FFFD,
  // every '</w>' turned into a space. Throws Error for ids outside the vocabulary.
  std::string decode(const std::vector<int>& ids) const;

  std::size_t vocabulary_size() const { return token_bytes_.size(); }

 private:
  std::vector<int> bpe(const std::string& word_bytes) const;

  struct Merge {
    int rank;    // position in the merge list: lower merges first
    int merged;  // id of the joined symbol
  };
  std::array<int, 256> byte_id_{}, end_byte_id_{};  // id of each byte as a symbol, alone / with '</w>'
  std::unordered_map<uint64_t, Merge> merges_;      // key: left id << 32 | right id
  std::vector<std::string> token_bytes_;            // raw bytes of each id, '</w>' spelled out

  // CLIP caches the BPE of every word it has seen; bounded here so a long-running process
  // cannot grow without limit. Behind a pointer so the tokenizer stays movable.
  struct Cache {
    std::mutex mutex;
    std::unordered_map<std::string, std::vector<int>> words;
  };
  std::unique_ptr<Cache> cache_ = std::make_unique<Cache>();
};

// The vocabulary a CLI uses when --vocab is not given: $SLAMVDB_CLIP_VOCAB, else
// SLAMVDB_SOURCE_DIR/../shared/clip/bpe_simple_vocab_16e6.txt.gz; throws Error naming both if absent.
std::filesystem::path default_clip_vocab_path();

}  // namespace slamvdb
