#include "slamvdb/inference/clip_tokenizer.hpp"

#include <unistd.h>
#include <zlib.h>

#include <algorithm>
#include <cstdlib>
#include <optional>

#include "slamvdb/core/error.hpp"
#include "slamvdb/core/regular_file.hpp"
#include "slamvdb/inference/clip_text_clean.hpp"

namespace slamvdb {
namespace {

constexpr int kMerges = 49152 - 256 - 2;  // the merge lines CLIP reads after the header line
constexpr std::size_t kMaxCachedWords = 1 << 16;
constexpr std::string_view kEndOfWord = "</w>";

// CLIP's bytes_to_unicode: printable Latin-1 bytes stand for themselves, the other 68 bytes for
// U+0100.. in byte order. Returns byte -> symbol code point.
std::array<char32_t, 256> byte_symbols() {
  std::array<char32_t, 256> symbol{};
  char32_t next = 256;
  for (int b = 0; b < 256; ++b) {
    const bool printable = (b >= '!' && b <= '~') || (b >= 0xA1 && b <= 0xAC) || (b >= 0xAE && b <= 0xFF);
    symbol[b] = printable ? static_cast<char32_t>(b) : next++;
  }
  return symbol;
}

// The first `lines` lines of the gzip file (CLIP reads no further; the rest is never inflated).
std::vector<std::string> read_gzip_lines(const std::filesystem::path& path, std::size_t lines) {
  std::error_code ec;
  if (!std::filesystem::exists(path, ec) && !ec) throw Error("CLIP BPE vocabulary not found: " + path.string());
  // Opened as a regular file (a FIFO is refused instead of blocking), then handed to zlib.
  const RegularFile regular(path, "CLIP BPE vocabulary");
  const int fd = ::dup(regular.fd());
  if (fd < 0) throw Error("cannot open CLIP BPE vocabulary " + path.string());
  const std::unique_ptr<gzFile_s, int (*)(gzFile)> file(gzdopen(fd, "rb"), gzclose);
  if (!file) {
    ::close(fd);
    throw Error("cannot open CLIP BPE vocabulary " + path.string());
  }
  std::string text;
  std::vector<std::string> out;
  std::array<char, 1 << 16> chunk;
  while (out.size() < lines) {
    const int n = gzread(file.get(), chunk.data(), static_cast<unsigned>(chunk.size()));
    if (n < 0) {
      int code = 0;
      throw Error("CLIP BPE vocabulary " + path.string() + " is corrupt: " + gzerror(file.get(), &code));
    }
    if (gzdirect(file.get())) throw Error("CLIP BPE vocabulary " + path.string() + " is not gzip-compressed");
    text.append(chunk.data(), static_cast<std::size_t>(n));
    std::size_t start = 0;
    for (std::size_t nl; out.size() < lines && (nl = text.find('\n', start)) != std::string::npos; start = nl + 1)
      out.push_back(text.substr(start, nl - start));
    text.erase(0, start);
    if (n == 0) break;
  }
  if (out.size() < lines)
    throw Error("CLIP BPE vocabulary " + path.string() + " is truncated: " + std::to_string(out.size()) +
                " lines, need " + std::to_string(lines));
  return out;
}

// Replacement-decoding as Python's bytes.decode('utf-8', errors='replace'): each maximal
// ill-formed subsequence becomes one U+FFFD.
std::string utf8_replace_invalid(std::string_view bytes) {
  std::string out;
  for (std::size_t i = 0; i < bytes.size();) {
    const auto b = [&](std::size_t k) { return static_cast<uint8_t>(bytes[k]); };
    const uint8_t b0 = b(i);
    int n = 0;
    uint8_t lo = 0x80, hi = 0xBF;  // allowed range of the second byte (Unicode table 3-7)
    if (b0 < 0x80) n = 1;
    else if (b0 >= 0xC2 && b0 <= 0xDF) n = 2;
    else if (b0 >= 0xE0 && b0 <= 0xEF) n = 3, lo = b0 == 0xE0 ? 0xA0 : 0x80, hi = b0 == 0xED ? 0x9F : 0xBF;
    else if (b0 >= 0xF0 && b0 <= 0xF4) n = 4, lo = b0 == 0xF0 ? 0x90 : 0x80, hi = b0 == 0xF4 ? 0x8F : 0xBF;
    int good = n ? 1 : 0;
    while (good && good < n && i + good < bytes.size()) {
      const uint8_t c = b(i + good);
      if (good == 1 ? (c < lo || c > hi) : (c & 0xC0) != 0x80) break;
      ++good;
    }
    if (good == n && n > 0) out.append(bytes.substr(i, n));
    else out += "\xEF\xBF\xBD";
    i += std::max(good, 1);
  }
  return out;
}

// CLIP's pre-tokenisation: regex findall of the pattern in clip_tokenizer.hpp over cleaned text.
std::vector<std::u32string_view> split_words(std::u32string_view t) {
  static constexpr std::u32string_view kLiterals[] = {U"<|startoftext|>", U"<|endoftext|>", U"'s", U"'t",
                                                      U"'re", U"'ve", U"'m", U"'ll", U"'d"};
  const auto literal_at = [&](std::size_t p, std::u32string_view lit) {
    if (p + lit.size() > t.size()) return false;
    for (std::size_t i = 0; i < lit.size(); ++i)
      if (!clip_case_equal(t[p + i], lit[i])) return false;
    return true;
  };
  std::vector<std::u32string_view> words;
  for (std::size_t p = 0; p < t.size();) {
    std::size_t len = 0;
    for (const auto lit : kLiterals)
      if (literal_at(p, lit)) {
        len = lit.size();
        break;
      }
    if (len == 0) {
      if (is_clip_letter(t[p])) {
        while (p + len < t.size() && is_clip_letter(t[p + len])) ++len;
      } else if (is_clip_number(t[p])) {
        len = 1;
      } else {
        while (p + len < t.size() && is_clip_other(t[p + len])) ++len;
      }
    }
    if (len == 0) {
      ++p;  // whitespace, or a character no alternative matches
      continue;
    }
    words.push_back(t.substr(p, len));
    p += len;
  }
  return words;
}

}  // namespace

ClipTokenizer::ClipTokenizer(const std::filesystem::path& merges_gz) {
  const std::vector<std::string> lines = read_gzip_lines(merges_gz, kMerges + 1);
  if (lines[0].find("#version") == std::string::npos)
    throw Error("CLIP BPE vocabulary " + merges_gz.string() + " does not start with a '#version' header");

  const std::array<char32_t, 256> symbol = byte_symbols();
  std::array<int, 256 + 68> byte_of_symbol;  // symbol code point -> byte, -1 for no symbol
  byte_of_symbol.fill(-1);
  for (int b = 0; b < 256; ++b) byte_of_symbol[symbol[b]] = b;
  const auto symbols_to_bytes = [&](std::string_view utf8) -> std::optional<std::string> {
    std::u32string chars;
    try {
      chars = utf8_to_utf32(utf8);
    } catch (const Error&) {
      return std::nullopt;
    }
    std::string bytes;
    for (char32_t c : chars) {
      if (c >= byte_of_symbol.size() || byte_of_symbol[c] < 0) return std::nullopt;
      bytes.push_back(static_cast<char>(byte_of_symbol[c]));
    }
    return bytes;
  };

  // The vocabulary in CLIP's order, as raw bytes: byte symbols, the same with '</w>', merges, specials.
  token_bytes_.reserve(512 + kMerges + 2);
  std::vector<int> order(256);
  for (int b = 0; b < 256; ++b) order[b] = b;
  std::stable_partition(order.begin(), order.end(), [&](int b) { return symbol[b] == static_cast<char32_t>(b); });
  for (int b : order) token_bytes_.emplace_back(1, static_cast<char>(b));
  for (int b : order) token_bytes_.push_back(std::string(1, static_cast<char>(b)) + std::string(kEndOfWord));

  std::vector<std::pair<std::string, std::string>> merges;
  merges.reserve(kMerges);
  for (int m = 1; m <= kMerges; ++m) {
    const std::string& line = lines[m];
    std::vector<std::string> parts;
    for (std::size_t p = 0; p < line.size();) {
      const std::size_t b = line.find_first_not_of(" \t\r\f\v", p);
      if (b == std::string::npos) break;
      const std::size_t e = std::min(line.find_first_of(" \t\r\f\v", b), line.size());
      const std::optional<std::string> raw = symbols_to_bytes(std::string_view(line).substr(b, e - b));
      if (!raw)
        throw Error("CLIP BPE vocabulary " + merges_gz.string() + " line " + std::to_string(m + 1) +
                    " holds a character that is no byte symbol: '" + line + "'");
      parts.push_back(*raw);
      p = e;
    }
    if (parts.size() != 2)
      throw Error("CLIP BPE vocabulary " + merges_gz.string() + " line " + std::to_string(m + 1) +
                  " is not a merge of two symbols: '" + line + "'");
    token_bytes_.push_back(parts[0] + parts[1]);
    merges.emplace_back(std::move(parts[0]), std::move(parts[1]));
  }
  token_bytes_.emplace_back("<|startoftext|>");
  token_bytes_.emplace_back("<|endoftext|>");

  // As CLIP's dicts: a string repeated in the vocabulary (or a pair in the merges) keeps its last id.
  std::unordered_map<std::string, int> id_of;
  id_of.reserve(token_bytes_.size());
  for (int id = 0; id < static_cast<int>(token_bytes_.size()); ++id) id_of.insert_or_assign(token_bytes_[id], id);
  for (int b = 0; b < 256; ++b) {
    byte_id_[b] = id_of.at(std::string(1, static_cast<char>(b)));
    end_byte_id_[b] = id_of.at(std::string(1, static_cast<char>(b)) + std::string(kEndOfWord));
  }
  merges_.reserve(merges.size());
  for (int rank = 0; rank < static_cast<int>(merges.size()); ++rank) {
    const auto& [left, right] = merges[rank];
    const auto l = id_of.find(left), r = id_of.find(right);
    if (l == id_of.end() || r == id_of.end()) continue;  // a pair of non-symbols can never occur in a word
    const uint64_t key = static_cast<uint64_t>(l->second) << 32 | static_cast<uint32_t>(r->second);
    merges_.insert_or_assign(key, Merge{rank, id_of.at(left + right)});
  }
}

std::vector<int> ClipTokenizer::bpe(const std::string& word) const {
  {
    std::lock_guard lock(cache_->mutex);
    if (const auto it = cache_->words.find(word); it != cache_->words.end()) return it->second;
  }
  std::vector<int> symbols;
  symbols.reserve(word.size());
  for (std::size_t i = 0; i < word.size(); ++i)
    symbols.push_back((i + 1 == word.size() ? end_byte_id_ : byte_id_)[static_cast<uint8_t>(word[i])]);

  while (symbols.size() > 1) {
    const Merge* best = nullptr;
    uint64_t best_key = 0;
    for (std::size_t i = 0; i + 1 < symbols.size(); ++i) {
      const uint64_t key = static_cast<uint64_t>(symbols[i]) << 32 | static_cast<uint32_t>(symbols[i + 1]);
      const auto it = merges_.find(key);
      if (it != merges_.end() && (!best || it->second.rank < best->rank)) {
        best = &it->second;
        best_key = key;
      }
    }
    if (!best) break;
    const int left = static_cast<int>(best_key >> 32), right = static_cast<int>(best_key & 0xFFFFFFFFu);
    std::vector<int> merged;
    merged.reserve(symbols.size());
    for (std::size_t i = 0; i < symbols.size(); ++i) {
      if (i + 1 < symbols.size() && symbols[i] == left && symbols[i + 1] == right) {
        merged.push_back(best->merged);
        ++i;
      } else {
        merged.push_back(symbols[i]);
      }
    }
    symbols = std::move(merged);
  }

  std::lock_guard lock(cache_->mutex);
  if (cache_->words.size() >= kMaxCachedWords) cache_->words.clear();
  cache_->words.emplace(word, symbols);
  return symbols;
}

std::vector<int> ClipTokenizer::encode(std::string_view utf8_text) const {
  const std::u32string text = clip_clean_text(utf8_to_utf32(utf8_text));
  std::vector<int> ids;
  for (const std::u32string_view word : split_words(text)) {
    const std::string bytes = utf32_to_utf8(word);
    if (bytes == "<|startoftext|>") {
      ids.push_back(kStartToken);
    } else if (bytes == "<|endoftext|>") {
      ids.push_back(kEndToken);
    } else {
      const std::vector<int> pieces = bpe(bytes);
      ids.insert(ids.end(), pieces.begin(), pieces.end());
    }
  }
  return ids;
}

std::vector<int64_t> ClipTokenizer::tokenize(std::string_view utf8_text, int context_length, bool truncate) const {
  if (context_length < 2)
    throw Error("CLIP context length must hold the start and end tokens (>= 2), got " + std::to_string(context_length));
  std::vector<int64_t> tokens = {kStartToken};
  for (int id : encode(utf8_text)) tokens.push_back(id);
  tokens.push_back(kEndToken);
  if (tokens.size() > static_cast<std::size_t>(context_length)) {
    if (!truncate) {
      const std::string shown = utf8_text.size() > 80 ? std::string(utf8_text.substr(0, 80)) + "..." : std::string(utf8_text);
      throw Error("text is " + std::to_string(tokens.size()) + " CLIP tokens long with start and end, more than the "
                  "context length " + std::to_string(context_length) + ": '" + shown + "'");
    }
    tokens.resize(context_length);
    tokens.back() = kEndToken;
  }
  tokens.resize(context_length, 0);
  return tokens;
}

std::string ClipTokenizer::decode(const std::vector<int>& ids) const {
  std::string bytes;
  for (int id : ids) {
    if (id < 0 || id >= static_cast<int>(token_bytes_.size()))
      throw Error("CLIP token id " + std::to_string(id) + " is outside the vocabulary [0, " +
                  std::to_string(token_bytes_.size()) + ")");
    bytes += token_bytes_[id];
  }
  const std::string text = utf8_replace_invalid(bytes);
  std::string spaced;
  std::size_t p = 0;
  for (std::size_t q; (q = text.find(kEndOfWord, p)) != std::string::npos; p = q + kEndOfWord.size())
    spaced.append(text, p, q - p).push_back(' ');
  return spaced.append(text, p);
}

std::filesystem::path default_clip_vocab_path() {
  const std::filesystem::path shared =
      std::filesystem::path(SLAMVDB_SOURCE_DIR) / ".." / "shared" / "clip" / "bpe_simple_vocab_16e6.txt.gz";
  const char* env = std::getenv("SLAMVDB_CLIP_VOCAB");
  std::error_code ec;
  if (env && *env) {
    if (std::filesystem::is_regular_file(env, ec)) return env;
    throw Error(std::string("CLIP BPE vocabulary not found: $SLAMVDB_CLIP_VOCAB is ") + env +
                ", which does not exist (the default would be " + shared.lexically_normal().string() + ")");
  }
  if (std::filesystem::is_regular_file(shared, ec)) return shared.lexically_normal();
  throw Error("CLIP BPE vocabulary not found: set $SLAMVDB_CLIP_VOCAB or pass --vocab (looked for " +
              shared.lexically_normal().string() + ")");
}

}  // namespace slamvdb
