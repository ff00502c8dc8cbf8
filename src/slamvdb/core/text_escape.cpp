#include "slamvdb/core/text_escape.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cstdint>

namespace slamvdb {

namespace {

// Length of the well-formed UTF-8 sequence at text[i] (Unicode table 3-7), 0 if ill-formed;
// its code point in `cp`.
std::size_t utf8_sequence(std::string_view text, std::size_t i, char32_t& cp) {
  const auto byte = [&](std::size_t k) { return static_cast<uint8_t>(text[k]); };
  const uint8_t b0 = byte(i);
  if (b0 < 0x80) {
    cp = b0;
    return 1;
  }
  std::size_t n = 0;
  uint8_t lo = 0x80, hi = 0xBF;  // allowed range of the second byte
  if (b0 >= 0xC2 && b0 <= 0xDF) n = 2;
  else if (b0 == 0xE0) n = 3, lo = 0xA0;
  else if (b0 >= 0xE1 && b0 <= 0xEC) n = 3;
  else if (b0 == 0xED) n = 3, hi = 0x9F;  // no surrogates
  else if (b0 >= 0xEE && b0 <= 0xEF) n = 3;
  else if (b0 == 0xF0) n = 4, lo = 0x90;
  else if (b0 >= 0xF1 && b0 <= 0xF3) n = 4;
  else if (b0 == 0xF4) n = 4, hi = 0x8F;
  else return 0;
  if (i + n > text.size()) return 0;
  if (byte(i + 1) < lo || byte(i + 1) > hi) return 0;
  for (std::size_t k = 2; k < n; ++k)
    if (byte(i + k) < 0x80 || byte(i + k) > 0xBF) return 0;
  cp = static_cast<char32_t>(b0 & (0xFF >> (n + 1)));
  for (std::size_t k = 1; k < n; ++k) cp = (cp << 6) | (byte(i + k) & 0x3F);
  return n;
}

// C1 controls, line / paragraph separators, bidirectional embeddings, overrides and isolates.
bool is_invisible_control(char32_t cp) {
  return (cp >= 0x80 && cp <= 0x9F) || cp == 0x2028 || cp == 0x2029 || (cp >= 0x202A && cp <= 0x202E) ||
         (cp >= 0x2066 && cp <= 0x2069);
}

bool is_control(char32_t cp) { return cp < 0x20 || cp == 0x7F || is_invisible_control(cp); }

std::string escape(std::string_view text, std::size_t max_bytes, bool keep_newlines) {
  std::string out;
  out.reserve(std::min(text.size(), max_bytes) + 8);
  std::size_t i = 0;
  while (i < text.size() && i < max_bytes) {
    char32_t cp = 0;
    const std::size_t n = utf8_sequence(text, i, cp);
    if (n == 0) {
      out += fmt::format("\\x{:02x}", static_cast<uint8_t>(text[i]));
      ++i;
      continue;
    }
    if (cp == '\n') out += keep_newlines ? "\n" : "\\n";
    else if (cp == '\r') out += "\\r";
    else if (cp == '\t') out += "\\t";
    else if (cp < 0x20 || cp == 0x7F) out += fmt::format("\\x{:02x}", static_cast<unsigned>(cp));
    else if (is_invisible_control(cp)) out += fmt::format("\\u{{{:04x}}}", static_cast<unsigned>(cp));
    else out.append(text.substr(i, n));
    i += n;
  }
  if (i < text.size()) out += fmt::format("... ({} more bytes)", text.size() - i);
  return out;
}

}  // namespace

std::string escape_control(std::string_view text, std::size_t max_bytes) { return escape(text, max_bytes, false); }

std::string escape_control_keep_lines(std::string_view text) { return escape(text, std::string_view::npos, true); }

std::string markdown_cell(std::string_view text) {
  std::string marked;
  marked.reserve(text.size() + 4);
  for (const char c : text) {
    if (std::string_view("|*_`[]<>\\").find(c) != std::string_view::npos) marked += '\\';
    marked += c;
  }
  return escape_control(marked);
}

std::string display_name_problem(std::string_view name) {
  if (name.empty()) return "is empty";
  if (name.size() > kMaxDisplayNameBytes)
    return fmt::format("is {} bytes long; at most {} are allowed", name.size(), kMaxDisplayNameBytes);
  for (std::size_t i = 0; i < name.size();) {
    char32_t cp = 0;
    const std::size_t n = utf8_sequence(name, i, cp);
    if (n == 0) return fmt::format("is not valid UTF-8 (byte {} is \\x{:02x})", i + 1, static_cast<uint8_t>(name[i]));
    if (is_control(cp))
      return fmt::format("holds the control character {} at byte {}", escape_control(name.substr(i, n)), i + 1);
    i += n;
  }
  if (name.front() == ' ' || name.back() == ' ') return "begins or ends with a space";
  return {};
}

}  // namespace slamvdb
