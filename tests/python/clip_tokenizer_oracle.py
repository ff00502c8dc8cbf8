#!/usr/bin/env python3
"""Test oracle for slamvdb's C++ CLIP tokenizer (src/slamvdb/inference/clip_tokenizer.cpp).

An independent Python re-implementation of OpenAI CLIP's simple_tokenizer (basic_clean,
whitespace_clean, lower-casing, the pre-tokenisation regex, byte-level BPE) on top of the
`regex` module, `html` and `unicodedata`, used only to produce expected token ids for tests.

basic_clean starts with ftfy.fix_text. When the `ftfy` package is importable it is used. When it
is not (Debian 12 does not package it), `fix_text_without_mojibake_repair` below transcribes the
steps of ftfy 6.3's default fix_text except mojibake repair (fix_encoding), which is exactly the
subset the C++ tokenizer reproduces; on ordinary text (no mojibake) both give the same result.

Usage:
  clip_tokenizer_oracle.py --vocab bpe_simple_vocab_16e6.txt.gz "a photo of a cat" ...
      prints one line of space-separated BPE ids (no start/end tokens) per text
  clip_tokenizer_oracle.py --vocab PATH --json < texts.json
      reads a JSON array of strings, writes a JSON array of id lists
"""
import argparse
import gzip
import html
import html.entities
import json
import re as stdlib_re
import sys
import unicodedata

import regex

try:
    import ftfy
except ImportError:
    ftfy = None


def _html_entities_ftfy():
    entities = {}
    for name, char in html.entities.html5.items():
        if name.endswith(";"):
            entities["&" + name] = char
            if name == name.lower():
                upper = "&" + name.upper()
                if html.unescape(upper) == upper:
                    entities[upper] = char.upper()
    return entities


_ENTITIES = _html_entities_ftfy()
_ENTITY_RE = stdlib_re.compile(r"&#?[0-9A-Za-z]{1,24};")
_ANSI_RE = stdlib_re.compile("\033\\[((?:\\d|;)*)([a-zA-Z])")
_LIGATURES = {ord(k): v for k, v in {
    "Ĳ": "IJ", "ĳ": "ij", "ŉ": "ʼn", "Ǳ": "DZ", "ǲ": "Dz", "ǳ": "dz", "Ǆ": "DŽ", "ǅ": "Dž", "ǆ": "dž",
    "Ǉ": "LJ", "ǈ": "Lj", "ǉ": "lj", "Ǌ": "NJ", "ǋ": "Nj", "ǌ": "nj", "ﬀ": "ff", "ﬁ": "fi", "ﬂ": "fl",
    "ﬃ": "ffi", "ﬄ": "ffl", "ﬅ": "ſt", "ﬆ": "st"}.items()}
_WIDTH = {0x3000: " "}
_WIDTH.update({i: unicodedata.normalize("NFKC", chr(i)) for i in range(0xFF01, 0xFFF0)
               if unicodedata.normalize("NFKC", chr(i)) != chr(i)})
_CONTROLS = {i: None for i in [*range(0x00, 0x09), 0x0B, *range(0x0E, 0x20), 0x7F, *range(0x206A, 0x2070),
                               0xFEFF, *range(0xFFF9, 0xFFFD)]}


def _unescape_entity(match):
    text = match.group(0)
    if text in _ENTITIES:
        return _ENTITIES[text]
    if text.startswith("&#"):
        unescaped = html.unescape(text)
        return text if ";" in unescaped else unescaped
    return text


def _c1_as_windows_1252(match):
    """ftfy's 'sloppy' Windows-1252: the five bytes it leaves undefined stay as they are."""
    return match.group(0).encode("latin-1").decode("windows-1252", "ignore") or match.group(0)


def _fix_segment(text, unescape):
    while True:
        original = text
        if unescape:
            text = _ENTITY_RE.sub(_unescape_entity, text)
        text = stdlib_re.sub("[\x80-\x9f]", _c1_as_windows_1252, text)
        text = text.translate(_LIGATURES).translate(_WIDTH)
        text = stdlib_re.sub("[\u201c-\u201f]", '"', text)
        text = stdlib_re.sub("[\u02bc\u2018-\u201b]", "'", text)
        text = (text.replace("\r\n", "\n").replace("\r", "\n").replace("\u2028", "\n")
                .replace("\u2029", "\n").replace("\u0085", "\n"))
        text = _ANSI_RE.sub("", text)
        text = text.translate(_CONTROLS)
        text = unicodedata.normalize("NFC", text)
        if text == original:
            return text


def fix_text_without_mojibake_repair(text):
    out, pos, unescape = [], 0, True
    while pos < len(text):
        end = text.find("\n", pos) + 1 or len(text)
        end = min(end, pos + 1_000_000)
        segment = text[pos:end]
        if "<" in segment:
            unescape = False
        out.append(_fix_segment(segment, unescape))
        pos = end
    return "".join(out)


def fix_text(text):
    return ftfy.fix_text(text) if ftfy is not None else fix_text_without_mojibake_repair(text)


def byte_chars():
    """CLIP's bytes_to_unicode, in its order: printable bytes map to themselves, the rest to 256 + n."""
    printable = [*range(ord("!"), ord("~") + 1), *range(ord("¡"), ord("¬") + 1), *range(ord("®"), ord("ÿ") + 1)]
    chars = {b: chr(b) for b in printable}
    for b in range(256):
        if b not in chars:
            chars[b] = chr(256 + len(chars) - len(printable))
    return chars


class Oracle:
    PATTERN = regex.compile(r"""<\|startoftext\|>|<\|endoftext\|>|'s|'t|'re|'ve|'m|'ll|'d|[\p{L}]+|[\p{N}]|"""
                            r"""[^\s\p{L}\p{N}]+""", regex.IGNORECASE)

    def __init__(self, vocab_gz):
        self.byte_char = byte_chars()
        lines = gzip.open(vocab_gz).read().decode("utf-8").split("\n")[1:49152 - 256 - 2 + 1]
        merges = [tuple(line.split()) for line in lines]
        base = list(self.byte_char.values())
        vocab = base + [c + "</w>" for c in base] + ["".join(m) for m in merges]
        vocab += ["<|startoftext|>", "<|endoftext|>"]
        self.ids = {token: i for i, token in enumerate(vocab)}
        self.rank = {pair: i for i, pair in enumerate(merges)}

    def bpe(self, token):
        if token in ("<|startoftext|>", "<|endoftext|>"):
            return [token]
        symbols = list(token[:-1]) + [token[-1] + "</w>"]
        while len(symbols) > 1:
            ranked = [(self.rank[p], p) for p in zip(symbols, symbols[1:]) if p in self.rank]
            if not ranked:
                break
            first, second = min(ranked)[1]
            merged, i = [], 0
            while i < len(symbols):
                if i + 1 < len(symbols) and symbols[i] == first and symbols[i + 1] == second:
                    merged.append(first + second)
                    i += 2
                else:
                    merged.append(symbols[i])
                    i += 1
            symbols = merged
        return symbols

    def encode(self, text):
        text = html.unescape(html.unescape(fix_text(text))).strip()
        text = regex.sub(r"\s+", " ", text).strip().lower()
        ids = []
        for piece in self.PATTERN.findall(text):
            token = "".join(self.byte_char[b] for b in piece.encode("utf-8"))
            ids.extend(self.ids[s] for s in self.bpe(token))
        return ids


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--vocab", required=True)
    parser.add_argument("--json", action="store_true", help="JSON array of strings on stdin")
    parser.add_argument("texts", nargs="*")
    args = parser.parse_args()
    oracle = Oracle(args.vocab)
    if args.json:
        json.dump([oracle.encode(t) for t in json.load(sys.stdin)], sys.stdout)
    else:
        for text in args.texts:
            print(" ".join(map(str, oracle.encode(text))))


if __name__ == "__main__":
    main()
