#pragma once
// Text that comes from files (model ids, class names, map metadata, tokens quoted in error
// messages) made safe to print: a control character in it could otherwise move the cursor, clear
// the screen or rewrite earlier lines of a terminal (ESC sequences), or hide text (CR, bidi
// overrides).
#include <cstddef>
#include <string>
#include <string_view>

namespace slamvdb {

// `text` with every control character replaced by a visible escape: \n \r \t as such, other C0
// bytes and DEL as \xNN, C1 controls (U+0080..U+009F) and the Unicode line / paragraph
// separators and bidirectional overrides as \u{NNNN}, and bytes that are not valid UTF-8 as \xNN.
// Printable text (ASCII and valid UTF-8) is unchanged, backslashes included: the result is for
// display, not meant to be parsed back. Longer than `max_bytes` input bytes, the rest is replaced by
// "... (N more bytes)".
std::string escape_control(std::string_view text, std::size_t max_bytes = std::string_view::npos);

// The same, but line breaks ('\n') are kept: for multi-line reports.
std::string escape_control_keep_lines(std::string_view text);

}  // namespace slamvdb
