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

// `text` as one cell of a markdown table, printed or written: control characters escaped as by
// escape_control, and the characters markdown reads as syntax inside a cell (| ends the cell,
// * _ ` [ ] < > \ start emphasis, code, links, HTML or escapes) preceded by a backslash.
std::string markdown_cell(std::string_view text);

// The rule for names that people read in tables, legends and files (class names of query sets and
// ontologies, label names, ontology names): 1 to kMaxDisplayNameBytes bytes of valid UTF-8, no
// control character of any kind (none of what escape_control escapes: C0, DEL, C1, line and
// paragraph separators, bidirectional controls) and no space at either end. Commas, quotes and
// `|` are allowed: the CSV writer quotes them and markdown_cell escapes them.
inline constexpr std::size_t kMaxDisplayNameBytes = 64;
// The rule in words, for messages.
inline constexpr std::string_view kDisplayNameRule =
    "a name is 1 to 64 bytes of UTF-8 without control characters or spaces at either end";
// What breaks the rule in `name`, e.g. "holds the control character \x1b"; empty when it is a
// good name.
std::string display_name_problem(std::string_view name);

}  // namespace slamvdb
