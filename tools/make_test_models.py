#!/usr/bin/env python3
"""Test models: the stand-in networks (stand_in_networks.py) exported as TorchScript, for tests
and benchmarks, with reference inputs and outputs computed here in Python.

The real LSeg / CLIP weights are not available here, so the C++ TorchScript backend is tested on
modules with the SAME interfaces and structure but random weights (their outputs mean nothing).

  python3 tools/make_test_models.py --out DIR --vocab shared/clip/bpe_simple_vocab_16e6.txt.gz
      writes dense/image/text .pt + .json via the export scripts' own functions, the reference
      inputs and outputs computed here in Python (pre-processing included) as .npy, and
      throwing.pt (a model that raises) for the C++ tests.
  python3 tools/make_test_models.py --out DIR --vit-b16
      writes vitb16_dense.pt + .json: a ViT-B/16-sized LSeg-shaped network (12 layers, width 768,
      12 heads, patch 16) at the paper's 256 x 384 input -> 512 x 128 x 192, for the benchmark.
"""
import argparse
import gzip
import html
import os
import re
import sys

import numpy as np
import torch
import torch.nn as nn

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import export_clip  # noqa: E402
import export_lseg  # noqa: E402
from export_common import write_json  # noqa: E402
from stand_in_networks import TINY_CLIP, TINY_LSEG, VIT_B16_LSEG, TinyClip, TinyLSegNet, tiny_forward_vit  # noqa: E402


class Throwing(nn.Module):
    def forward(self, x):
        if bool(x.sum() > -1e30):
            raise RuntimeError("deliberate failure inside the model")
        return x


# ---------------------------------------------------------------- Python references
class ClipBpe:
    """CLIP's SimpleTokenizer + clip.tokenize, independent of the C++ one (without ftfy). The letter
    / number classes use Python's `re` to need nothing beyond torch and numpy; that equals CLIP's
    \\p{L} / \\p{N} on the ASCII prompts the test uses (tests/python/clip_tokenizer_oracle.py is
    the exact oracle for the tokenizer itself)."""

    PATTERN = re.compile(r"<\|startoftext\|>|<\|endoftext\|>|'s|'t|'re|'ve|'m|'ll|'d|[^\W\d_]+|\d|(?:[^\s\w]|_)+",
                         re.IGNORECASE)

    def __init__(self, merges_gz):
        bs = [*range(ord("!"), ord("~") + 1), *range(ord("¡"), ord("¬") + 1), *range(ord("®"), ord("ÿ") + 1)]
        cs = bs[:]
        extra = 0
        for b in range(256):
            if b not in bs:
                bs.append(b)
                cs.append(256 + extra)
                extra += 1
        self.byte_encoder = dict(zip(bs, map(chr, cs)))
        merges = gzip.open(merges_gz).read().decode("utf-8").split("\n")[1:49152 - 256 - 2 + 1]
        merges = [tuple(m.split()) for m in merges]
        vocab = list(self.byte_encoder.values())
        vocab += [v + "</w>" for v in vocab] + ["".join(m) for m in merges] + ["<|startoftext|>", "<|endoftext|>"]
        self.encoder = {v: i for i, v in enumerate(vocab)}
        self.ranks = {m: i for i, m in enumerate(merges)}

    def bpe(self, token):
        word = tuple(token[:-1]) + (token[-1] + "</w>",)
        while len(word) > 1:
            pairs = {(a, b) for a, b in zip(word, word[1:])}
            best = min(pairs, key=lambda pair: self.ranks.get(pair, float("inf")))
            if best not in self.ranks:
                break
            merged, i = [], 0
            while i < len(word):
                if i < len(word) - 1 and (word[i], word[i + 1]) == best:
                    merged.append(word[i] + word[i + 1])
                    i += 2
                else:
                    merged.append(word[i])
                    i += 1
            word = tuple(merged)
        return word

    def tokenize(self, text, context_length=77):
        text = re.sub(r"\s+", " ", html.unescape(html.unescape(text)).strip()).strip().lower()
        ids = [self.encoder["<|startoftext|>"]]
        for token in self.PATTERN.findall(text):
            token = "".join(self.byte_encoder[b] for b in token.encode("utf-8"))
            ids += [self.encoder[t] for t in self.bpe(token)]
        ids.append(self.encoder["<|endoftext|>"])
        if len(ids) > context_length:  # clip.tokenize(truncate=True)
            ids = ids[:context_length]
            ids[-1] = self.encoder["<|endoftext|>"]
        return ids + [0] * (context_length - len(ids))


def preprocess(image, spec):
    """uint8 H x W x 3 RGB -> 1 x 3 x h x w float32 network input, per the manifest's `input`.
    Only the resize-free cases (image already at size, or centre crop of an exactly short side)."""
    h, w = spec["height"], spec["width"]
    if spec["resize"] == "resize_short_center_crop":
        assert min(image.shape[0], image.shape[1]) == min(h, w), "reference does not resample"
        top = int(round((image.shape[0] - h) / 2.0))
        left = int(round((image.shape[1] - w) / 2.0))
        image = image[top:top + h, left:left + w]
    assert image.shape[:2] == (h, w), "reference does not resample"
    if spec["channel_order"] == "BGR":
        image = image[:, :, ::-1]
    x = (image.astype(np.float64) * spec["value_scale"] - np.array(spec["mean"])) / np.array(spec["std"])
    return torch.from_numpy(x.astype(np.float32).transpose(2, 0, 1).copy()).unsqueeze(0)


def run(path, x):
    with torch.no_grad():
        return torch.jit.load(path)(x)


def unit(v):
    return v / v.norm(dim=-1, keepdim=True)


def save_planar(path, array):
    """Saves as float32 with 3 dims, the shape the C++ side's read_feature_npy reads."""
    np.save(path, np.ascontiguousarray(array, dtype=np.float32))


def write_test_models(out, vocab):
    # One thread: these networks are tiny, and OpenMP threads that wait for each other on a
    # machine busy with other work make a 2 ms pass take hundreds of milliseconds.
    threads = 1
    rng = np.random.default_rng(7)
    torch.manual_seed(7)

    dense = export_lseg.export_dense(TinyLSegNet(TINY_LSEG), tiny_forward_vit, out, "dense", "tiny-lseg-random-init",
                                     TINY_LSEG["height"], TINY_LSEG["width"], threads)
    image = rng.integers(0, 256, size=(TINY_LSEG["height"], TINY_LSEG["width"], 3), dtype=np.uint8)
    features = run(os.path.join(out, "dense.pt"), preprocess(image, dense["input"]))[0]
    save_planar(os.path.join(out, "dense_input.npy"), image.transpose(2, 0, 1))
    save_planar(os.path.join(out, "dense_output.npy"), features.numpy())

    clip_model = TinyClip(TINY_CLIP)
    size = TINY_CLIP["image_size"]
    spec = export_clip.export_image(clip_model, out, "image", "tiny-clip-image-random-init", size, threads)
    image = rng.integers(0, 256, size=(size, size + 8, 3), dtype=np.uint8)  # centre crop drops 4 columns each side
    vector = unit(run(os.path.join(out, "image.pt"), preprocess(image, spec["input"])))[0]
    save_planar(os.path.join(out, "image_input.npy"), image.transpose(2, 0, 1))
    save_planar(os.path.join(out, "image_output.npy"), vector.numpy().reshape(-1, 1, 1))

    export_clip.export_text(clip_model, out, "text", "tiny-clip-text-random-init", os.path.abspath(vocab),
                            normalize=True, threads=threads)
    bpe = ClipBpe(vocab)
    assert bpe.tokenize("a photo of a cat")[:7] == [49406, 320, 1125, 539, 320, 2368, 49407], "BPE reference broken"
    prompts = ["tall grass", "a photo of a cat", "Dirt road, with PUDDLES!", "  gravel   trail ", "rock 42",
               " ".join(["bush"] * 100)]  # longer than the context: truncated, last token = end of text
    tokens = torch.tensor([bpe.tokenize(p) for p in prompts])
    vectors = unit(run(os.path.join(out, "text.pt"), tokens))
    with open(os.path.join(out, "text_prompts.txt"), "w") as f:
        f.write("\n".join(prompts) + "\n")
    save_planar(os.path.join(out, "text_output.npy"), vectors.numpy().T.reshape(-1, 1, len(prompts)))

    torch.jit.script(Throwing()).save(os.path.join(out, "throwing.pt"))
    throwing = export_lseg.dense_manifest("throwing", 64, 64, 16, threads)
    throwing["model_id"] = "deliberately-throwing"
    write_json(os.path.join(out, "throwing.json"), throwing)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True)
    p.add_argument("--vocab", help="CLIP merge list (bpe_simple_vocab_16e6.txt.gz) for the text model")
    p.add_argument("--vit-b16", action="store_true", help="only the ViT-B/16-sized dense model for benchmarks")
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)
    torch.set_num_threads(2)
    if args.vit_b16:
        torch.manual_seed(16)
        cfg = VIT_B16_LSEG
        export_lseg.export_dense(TinyLSegNet(cfg), tiny_forward_vit, args.out, "vitb16_dense",
                                 "vit-b16-lseg-random-init", cfg["height"], cfg["width"])
    else:
        if not args.vocab:
            raise SystemExit("--vocab is required for the test models")
        write_test_models(args.out, args.vocab)
    print(f"wrote test models to {args.out}")


if __name__ == "__main__":
    main()
