#pragma once
// The text clean-up OpenAI CLIP's tokenizer (clip/simple_tokenizer.py) applies before BPE:
//   basic_clean:      ftfy.fix_text, html.unescape twice, strip
//   whitespace_clean: collapse whitespace runs to one space, strip
//   then lower-casing.
// Character properties, case mapping and normalisation come from ICU, so the Unicode version is
// ICU's (72: Unicode 15.0); Python's own tables may differ for characters added since.
//
// ftfy.fix_text is reproduced with ftfy 6.3's default configuration EXCEPT mojibake repair
// (fix_encoding with restore_byte_a0, replace_lossy_sequences and decode_inconsistent_utf8): text
// that was UTF-8 decoded as Latin-1 / Windows-125x / MacRoman ("cafÃ©") is left as it is, where
// ftfy would re-decode it. Everything else is: HTML entities (not in lines after one containing
// '<'), C1 controls as Windows-1252, Latin ligatures, full/half-width forms, curly quotes, line
// breaks, terminal escapes, invisible control characters, NFC, repeated until nothing changes.
#include <string>
#include <string_view>

namespace slamvdb {

std::u32string utf8_to_utf32(std::string_view utf8);  // throws Error naming the offset of bad UTF-8
std::string utf32_to_utf8(std::u32string_view text);

std::u32string python_html_unescape(std::u32string_view text);  // Python's html.unescape
std::u32string ftfy_fix_text(std::u32string_view text);         // see the file comment
std::u32string clip_clean_text(std::u32string_view text);       // basic_clean, whitespace_clean, lower

// The classes of the pre-tokenisation regex (regex module, IGNORECASE).
bool is_clip_letter(char32_t c);      // [\p{L}]
bool is_clip_number(char32_t c);      // [\p{N}]
bool is_clip_other(char32_t c);       // [^\s\p{L}\p{N}]
bool clip_case_equal(char32_t c, char32_t ascii_lower);  // IGNORECASE literal match

}  // namespace slamvdb
