#include "slamvdb/inference/clip_text_clean.hpp"

#include <unicode/locid.h>
#include <unicode/normalizer2.h>
#include <unicode/uchar.h>
#include <unicode/unistr.h>

#include <algorithm>
#include <array>
#include <string>
#include <unordered_map>

#include "slamvdb/core/error.hpp"

namespace slamvdb {
namespace {

struct Html5Entity {
  std::string_view name, utf8;
};
constexpr Html5Entity kHtml5Entities[] = {
#include "clip_html_entities.inc"
};

// Windows-1252 for bytes 0x80..0x9F; the five it leaves undefined stay as the C1 control (the
// table behind both Python's html.unescape numeric references and ftfy's fix_c1_controls).
constexpr std::array<char32_t, 32> kWindows1252C1 = {
    0x20AC, 0x81,   0x201A, 0x0192, 0x201E, 0x2026, 0x2020, 0x2021, 0x02C6, 0x2030, 0x0160,
    0x2039, 0x0152, 0x8D,   0x017D, 0x8F,   0x90,   0x2018, 0x2019, 0x201C, 0x201D, 0x2022,
    0x2013, 0x2014, 0x02DC, 0x2122, 0x0161, 0x203A, 0x0153, 0x9D,   0x017E, 0x0178};

icu::UnicodeString to_icu(std::u32string_view s) {
  return icu::UnicodeString::fromUTF32(reinterpret_cast<const UChar32*>(s.data()), static_cast<int32_t>(s.size()));
}

std::u32string from_icu(const icu::UnicodeString& u) {
  std::u32string out;
  out.reserve(u.length());
  for (int32_t i = 0; i < u.length();) {
    const UChar32 c = u.char32At(i);
    out.push_back(static_cast<char32_t>(c));
    i += U16_LENGTH(c);
  }
  return out;
}

const icu::Normalizer2& normalizer(bool compatibility) {
  UErrorCode status = U_ZERO_ERROR;
  const icu::Normalizer2* n =
      compatibility ? icu::Normalizer2::getNFKCInstance(status) : icu::Normalizer2::getNFCInstance(status);
  if (U_FAILURE(status)) throw Error(std::string("ICU normaliser unavailable: ") + u_errorName(status));
  return *n;
}

std::u32string normalize(std::u32string_view s, bool compatibility) {
  UErrorCode status = U_ZERO_ERROR;
  const icu::UnicodeString out = normalizer(compatibility).normalize(to_icu(s), status);
  if (U_FAILURE(status)) throw Error(std::string("ICU normalisation failed: ") + u_errorName(status));
  return from_icu(out);
}

std::u32string to_lower(std::u32string_view s) { return from_icu(to_icu(s).toLower(icu::Locale::getRoot())); }
std::u32string to_upper(std::u32string_view s) { return from_icu(to_icu(s).toUpper(icu::Locale::getRoot())); }

// Python's str.isspace (what str.strip removes) and the regex module's \s (Unicode White_Space).
bool is_python_space(char32_t c) {
  return (c >= 0x09 && c <= 0x0D) || (c >= 0x1C && c <= 0x20) || c == 0x85 || c == 0xA0 || c == 0x1680 ||
         (c >= 0x2000 && c <= 0x200A) || c == 0x2028 || c == 0x2029 || c == 0x202F || c == 0x205F || c == 0x3000;
}
bool is_regex_space(char32_t c) { return is_python_space(c) && !(c >= 0x1C && c <= 0x1F); }

bool is_ascii_digit(char32_t c) { return c >= '0' && c <= '9'; }
bool is_ascii_hex(char32_t c) { return is_ascii_digit(c) || (c >= 'a' && c <= 'f') || (c >= 'A' && c <= 'F'); }
bool is_ascii_alnum(char32_t c) { return is_ascii_digit(c) || (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z'); }

std::u32string strip(std::u32string_view s) {
  std::size_t b = 0, e = s.size();
  while (b < e && is_python_space(s[b])) ++b;
  while (e > b && is_python_space(s[e - 1])) --e;
  return std::u32string(s.substr(b, e - b));
}

const std::unordered_map<std::string_view, std::u32string>& html5_entities() {
  static const auto table = [] {
    std::unordered_map<std::string_view, std::u32string> t;
    for (const auto& e : kHtml5Entities) t.emplace(e.name, utf8_to_utf32(e.utf8));
    return t;
  }();
  return table;
}

const std::u32string* find_html5(std::u32string_view name) {
  std::string key;
  for (char32_t c : name) {
    if (c >= 0x80) return nullptr;  // every entity name is ASCII
    key.push_back(static_cast<char>(c));
  }
  const auto& table = html5_entities();
  const auto it = table.find(key);
  return it == table.end() ? nullptr : &it->second;
}

// Python's html._replace_charref for a numeric reference, given the saturated value.
std::u32string numeric_charref(uint32_t num) {
  if (num == 0x00) return U"\uFFFD";
  if (num == 0x0D) return U"\r";
  if (num >= 0x80 && num <= 0x9F) return std::u32string(1, kWindows1252C1[num - 0x80]);
  if ((num >= 0xD800 && num <= 0xDFFF) || num > 0x10FFFF) return U"\uFFFD";
  const bool invalid = (num >= 0x01 && num <= 0x08) || num == 0x0B || (num >= 0x0E && num <= 0x1F) || num == 0x7F ||
                       (num >= 0xFDD0 && num <= 0xFDEF) || (num & 0xFFFE) == 0xFFFE;
  return invalid ? std::u32string() : std::u32string(1, static_cast<char32_t>(num));
}

uint32_t parse_saturated(std::u32string_view digits, uint32_t base) {
  uint32_t value = 0;
  for (char32_t c : digits) {
    const uint32_t d = is_ascii_digit(c) ? c - '0' : (c | 0x20) - 'a' + 10;
    value = std::min<uint32_t>(value * base + d, 0x110000);
  }
  return value;
}

// The fixers of ftfy 6.3's fix_and_explain loop, in its order.

// ftfy's HTML_ENTITIES: the HTML5 entities that end in ';', plus all-caps spellings of the
// lower-case ones that html.unescape would not decode (&EACUTE; -> É).
const std::unordered_map<std::u32string, std::u32string>& ftfy_entities() {
  static const auto table = [] {
    std::unordered_map<std::u32string, std::u32string> t;
    for (const auto& e : kHtml5Entities) {
      if (!e.name.ends_with(';')) continue;
      std::u32string name = U"&";
      name += utf8_to_utf32(e.name);
      const std::u32string value = utf8_to_utf32(e.utf8);
      t.insert_or_assign(name, value);
      if (!std::any_of(name.begin(), name.end(), [](char32_t c) { return c >= 'A' && c <= 'Z'; })) {
        std::u32string upper = name;
        for (char32_t& c : upper)
          if (c >= 'a' && c <= 'z') c -= 0x20;
        if (python_html_unescape(upper) == upper) t.insert_or_assign(upper, to_upper(value));
      }
    }
    return t;
  }();
  return table;
}

std::u32string ftfy_unescape_html(std::u32string_view s) {
  std::u32string out;
  for (std::size_t i = 0; i < s.size();) {
    std::size_t end = 0;  // end of a match of &#?[0-9A-Za-z]{1,24}; at i
    if (s[i] == '&') {
      for (std::size_t start : {i + 1 + (i + 1 < s.size() && s[i + 1] == '#'), i + 1}) {
        std::size_t k = start;
        while (k < s.size() && is_ascii_alnum(s[k])) ++k;
        if (k > start && k - start <= 24 && k < s.size() && s[k] == ';') {
          end = k + 1;
          break;
        }
      }
    }
    if (!end) {
      out.push_back(s[i++]);
      continue;
    }
    const std::u32string_view match = s.substr(i, end - i);
    const auto& table = ftfy_entities();
    if (const auto it = table.find(std::u32string(match)); it != table.end()) {
      out += it->second;
    } else if (match[1] == '#') {
      const std::u32string decoded = python_html_unescape(match);
      out += decoded.find(';') == std::u32string::npos ? decoded : std::u32string(match);
    } else {
      out += match;
    }
    i = end;
  }
  return out;
}

std::u32string fix_c1_controls(std::u32string_view s) {
  std::u32string out(s);
  for (char32_t& c : out)
    if (c >= 0x80 && c <= 0x9F) c = kWindows1252C1[c - 0x80];
  return out;
}

std::u32string fix_latin_ligatures(std::u32string_view s) {
  static const std::unordered_map<char32_t, std::u32string_view> ligatures = {
      {U'Ĳ', U"IJ"}, {U'ĳ', U"ij"}, {U'ŉ', U"ʼn"}, {U'Ǳ', U"DZ"}, {U'ǲ', U"Dz"}, {U'ǳ', U"dz"},
      {U'Ǆ', U"DŽ"}, {U'ǅ', U"Dž"}, {U'ǆ', U"dž"}, {U'Ǉ', U"LJ"}, {U'ǈ', U"Lj"}, {U'ǉ', U"lj"},
      {U'Ǌ', U"NJ"}, {U'ǋ', U"Nj"}, {U'ǌ', U"nj"}, {U'ﬀ', U"ff"}, {U'ﬁ', U"fi"}, {U'ﬂ', U"fl"},
      {U'ﬃ', U"ffi"}, {U'ﬄ', U"ffl"}, {U'ﬅ', U"ſt"}, {U'ﬆ', U"st"}};
  std::u32string out;
  for (char32_t c : s) {
    const auto it = ligatures.find(c);
    if (it == ligatures.end()) out.push_back(c);
    else out += it->second;
  }
  return out;
}

// U+3000 and the halfwidth/fullwidth forms block, each replaced by its NFKC form if different.
std::u32string fix_character_width(std::u32string_view s) {
  static const auto width_map = [] {
    std::unordered_map<char32_t, std::u32string> m = {{0x3000, U" "}};
    for (char32_t c = 0xFF01; c < 0xFFF0; ++c) {
      std::u32string alt = normalize(std::u32string(1, c), true);
      if (alt != std::u32string(1, c)) m.emplace(c, std::move(alt));
    }
    return m;
  }();
  std::u32string out;
  for (char32_t c : s) {
    const auto it = width_map.find(c);
    if (it == width_map.end()) out.push_back(c);
    else out += it->second;
  }
  return out;
}

std::u32string uncurl_quotes(std::u32string_view s) {
  std::u32string out(s);
  for (char32_t& c : out) {
    if (c >= 0x201C && c <= 0x201F) c = '"';
    else if (c == 0x02BC || (c >= 0x2018 && c <= 0x201B)) c = '\'';
  }
  return out;
}

std::u32string fix_line_breaks(std::u32string_view s) {
  std::u32string out;
  for (std::size_t i = 0; i < s.size(); ++i) {
    const char32_t c = s[i];
    if (c == '\r' && i + 1 < s.size() && s[i + 1] == '\n') continue;  // CRLF -> LF
    out.push_back(c == '\r' || c == 0x2028 || c == 0x2029 || c == 0x85 ? U'\n' : c);
  }
  return out;
}

// ESC [ (digits | ;)* letter, where a digit is any Unicode decimal digit (Python's \d).
std::u32string remove_terminal_escapes(std::u32string_view s) {
  std::u32string out;
  for (std::size_t i = 0; i < s.size();) {
    if (s[i] == 0x1B && i + 1 < s.size() && s[i + 1] == '[') {
      std::size_t k = i + 2;
      while (k < s.size() && (s[k] == ';' || u_charType(static_cast<UChar32>(s[k])) == U_DECIMAL_DIGIT_NUMBER)) ++k;
      if (k < s.size() && ((s[k] >= 'a' && s[k] <= 'z') || (s[k] >= 'A' && s[k] <= 'Z'))) {
        i = k + 1;
        continue;
      }
    }
    out.push_back(s[i++]);
  }
  return out;
}

std::u32string remove_control_chars(std::u32string_view s) {
  std::u32string out;
  for (char32_t c : s) {
    const bool control = c <= 0x08 || c == 0x0B || (c >= 0x0E && c <= 0x1F) || c == 0x7F ||
                         (c >= 0x206A && c <= 0x206F) || c == 0xFEFF || (c >= 0xFFF9 && c <= 0xFFFC);
    if (!control) out.push_back(c);
  }
  return out;
}

std::u32string ftfy_fix_segment(std::u32string text, bool unescape_html) {
  while (true) {
    const std::u32string original = text;
    if (unescape_html) text = ftfy_unescape_html(text);
    text = fix_c1_controls(text);
    text = fix_latin_ligatures(text);
    text = fix_character_width(text);
    text = uncurl_quotes(text);
    text = fix_line_breaks(text);
    text = remove_terminal_escapes(text);
    text = remove_control_chars(text);
    text = normalize(text, false);
    if (text == original) return text;
  }
}

}  // namespace

// &(#[0-9]+;? | #[xX][0-9a-fA-F]+;? | [^\t\n\f <&#;]{1,32};?), replaced as html._replace_charref does.
std::u32string python_html_unescape(std::u32string_view s) {
  if (s.find('&') == std::u32string_view::npos) return std::u32string(s);
  const auto in_name = [](char32_t c) {
    return c != '\t' && c != '\n' && c != '\f' && c != ' ' && c != '<' && c != '&' && c != '#' && c != ';';
  };
  std::u32string out;
  for (std::size_t i = 0; i < s.size();) {
    if (s[i] != '&') {
      out.push_back(s[i++]);
      continue;
    }
    const std::size_t j = i + 1;
    if (j < s.size() && s[j] == '#') {
      const bool hex = j + 1 < s.size() && (s[j + 1] == 'x' || s[j + 1] == 'X');
      std::size_t k = j + 1;
      while (k < s.size() && is_ascii_digit(s[k])) ++k;
      std::size_t digits_begin = j + 1;
      if (k == j + 1 && hex) {
        digits_begin = k = j + 2;
        while (k < s.size() && is_ascii_hex(s[k])) ++k;
      }
      if (k == digits_begin) {  // no digits: not a reference
        out.push_back(s[i++]);
        continue;
      }
      out += numeric_charref(parse_saturated(s.substr(digits_begin, k - digits_begin), digits_begin == j + 1 ? 10 : 16));
      i = k + (k < s.size() && s[k] == ';');
      continue;
    }
    std::size_t k = j;
    while (k < s.size() && k - j < 32 && in_name(s[k])) ++k;
    if (k == j) {
      out.push_back(s[i++]);
      continue;
    }
    if (k < s.size() && s[k] == ';') ++k;
    const std::u32string_view name = s.substr(j, k - j);
    if (const auto* value = find_html5(name)) {
      out += *value;
    } else {
      // The longest entity (at least 2 characters) that the name starts with, as the standard says.
      std::size_t x = name.size() - 1;
      const std::u32string* prefix = nullptr;
      for (; x > 1 && !(prefix = find_html5(name.substr(0, x))); --x) {
      }
      if (prefix) {
        out += *prefix;
        out += name.substr(x);
      } else {
        out += '&';
        out += name;
      }
    }
    i = k;
  }
  return out;
}

std::u32string ftfy_fix_text(std::u32string_view text) {
  // ftfy fixes line by line (at most 10^6 characters each); once a line holds a '<' the text may be
  // HTML, and entities are left alone from that line on.
  constexpr std::size_t kMaxSegment = 1'000'000;
  std::u32string out;
  bool unescape_html = true;
  for (std::size_t pos = 0; pos < text.size();) {
    const std::size_t newline = text.find('\n', pos);
    std::size_t end = newline == std::u32string_view::npos ? text.size() : newline + 1;
    end = std::min(end, pos + kMaxSegment);
    const std::u32string_view segment = text.substr(pos, end - pos);
    if (segment.find('<') != std::u32string_view::npos) unescape_html = false;
    out += ftfy_fix_segment(std::u32string(segment), unescape_html);
    pos = end;
  }
  return out;
}

std::u32string clip_clean_text(std::u32string_view text) {
  const std::u32string basic = strip(python_html_unescape(python_html_unescape(ftfy_fix_text(text))));
  std::u32string collapsed;
  for (std::size_t i = 0; i < basic.size();) {
    if (!is_regex_space(basic[i])) {
      collapsed.push_back(basic[i++]);
      continue;
    }
    collapsed.push_back(' ');
    while (i < basic.size() && is_regex_space(basic[i])) ++i;
  }
  return to_lower(strip(collapsed));
}

bool is_clip_letter(char32_t c) { return (U_GET_GC_MASK(static_cast<UChar32>(c)) & U_GC_L_MASK) != 0; }
bool is_clip_number(char32_t c) { return (U_GET_GC_MASK(static_cast<UChar32>(c)) & U_GC_N_MASK) != 0; }

bool is_clip_other(char32_t c) {
  if (is_regex_space(c) || is_clip_letter(c) || is_clip_number(c)) return false;
  // Under IGNORECASE the negated class also rejects a character whose case fold is a letter or a
  // number (U+0345 folds to iota); such a character matches no alternative and CLIP drops it.
  const auto folded = static_cast<char32_t>(u_foldCase(static_cast<UChar32>(c), U_FOLD_CASE_DEFAULT));
  return folded == c || !(is_clip_letter(folded) || is_clip_number(folded));
}

bool clip_case_equal(char32_t c, char32_t ascii_lower) {
  return c == ascii_lower || static_cast<char32_t>(u_foldCase(static_cast<UChar32>(c), U_FOLD_CASE_DEFAULT)) == ascii_lower;
}

}  // namespace slamvdb
