#!/usr/bin/env python3
"""Randomly initialised stand-ins for the paper's networks, for tests and benchmarks.

The real LSeg / CLIP weights are not available here, so the C++ TorchScript backend is tested on
modules with the SAME interfaces and structure but random weights (their outputs mean nothing):
  - TinyLSegNet: LSeg's structure (ViT with 4 tapped blocks, DPT reassemble + fusion blocks,
    head1 to the embedding dim), wrapped by export_lseg.LSegPixelEncoder:
    N x 3 x H x W -> N x C x H/2 x W/2, unit vectors per pixel.
  - TinyClip: CLIP's encode_text (token + position embedding, causal transformer, feature at the
    end-of-text token = argmax id, projection) and encode_image (ViT, class token, projection).

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
import json
import os
import re
import sys

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import export_clip  # noqa: E402
import export_lseg  # noqa: E402

TINY_LSEG = dict(height=64, width=96, patch=16, vit_width=32, depth=4, heads=2, hooks=[0, 1, 2, 3],
                 reassemble=[8, 16, 32, 32], features=16, out_dim=16)
VIT_B16_LSEG = dict(height=256, width=384, patch=16, vit_width=768, depth=12, heads=12, hooks=[2, 5, 8, 11],
                    reassemble=[96, 192, 384, 768], features=256, out_dim=512)
TINY_CLIP = dict(embed_dim=16, vocab_size=49408, context_length=77, text_width=32, text_layers=2, text_heads=2,
                 image_size=32, patch=8, vision_width=32, vision_layers=2, vision_heads=2)


# ---------------------------------------------------------------- LSeg-shaped dense encoder
class Attention(nn.Module):  # timm's ViT attention
    def __init__(self, dim, heads):
        super().__init__()
        self.num_heads = heads
        self.scale = (dim // heads) ** -0.5
        self.qkv = nn.Linear(dim, dim * 3)
        self.proj = nn.Linear(dim, dim)

    def forward(self, x):
        b, n, c = x.shape
        qkv = self.qkv(x).reshape(b, n, 3, self.num_heads, c // self.num_heads).permute(2, 0, 3, 1, 4)
        q, k, v = qkv[0], qkv[1], qkv[2]
        attn = ((q @ k.transpose(-2, -1)) * self.scale).softmax(dim=-1)
        return self.proj((attn @ v).transpose(1, 2).reshape(b, n, c))


class Block(nn.Module):  # timm's ViT block
    def __init__(self, dim, heads):
        super().__init__()
        self.norm1 = nn.LayerNorm(dim, eps=1e-6)
        self.attn = Attention(dim, heads)
        self.norm2 = nn.LayerNorm(dim, eps=1e-6)
        self.mlp = nn.Sequential(nn.Linear(dim, 4 * dim), nn.GELU(), nn.Linear(4 * dim, dim))

    def forward(self, x):
        x = x + self.attn(self.norm1(x))
        return x + self.mlp(self.norm2(x))


class VisionTransformer(nn.Module):
    def __init__(self, cfg):
        super().__init__()
        d, p = cfg["vit_width"], cfg["patch"]
        self.patch_embed = nn.Module()
        self.patch_embed.proj = nn.Conv2d(3, d, kernel_size=p, stride=p)
        self.cls_token = nn.Parameter(0.02 * torch.randn(1, 1, d))
        self.pos_embed = nn.Parameter(0.02 * torch.randn(1, 1 + (cfg["height"] // p) * (cfg["width"] // p), d))
        self.blocks = nn.ModuleList([Block(d, cfg["heads"]) for _ in range(cfg["depth"])])


class ProjectReadout(nn.Module):  # LSeg's readout="project"
    def __init__(self, dim):
        super().__init__()
        self.project = nn.Sequential(nn.Linear(2 * dim, dim), nn.GELU())

    def forward(self, x):
        readout = x[:, 0].unsqueeze(1).expand_as(x[:, 1:])
        return self.project(torch.cat((x[:, 1:], readout), -1))


class Transpose(nn.Module):
    def forward(self, x):
        return x.transpose(1, 2)


def reassemble(cfg, i):
    """LSeg's act_postprocess{1..4}: tokens -> grid at 1/4, 1/8, 1/16, 1/32 of the input."""
    d, f, grid = cfg["vit_width"], cfg["reassemble"][i], (cfg["height"] // cfg["patch"], cfg["width"] // cfg["patch"])
    layers = [ProjectReadout(d), Transpose(), nn.Unflatten(2, torch.Size(grid)), nn.Conv2d(d, f, 1)]
    if i == 0:
        layers.append(nn.ConvTranspose2d(f, f, kernel_size=4, stride=4))
    elif i == 1:
        layers.append(nn.ConvTranspose2d(f, f, kernel_size=2, stride=2))
    elif i == 3:
        layers.append(nn.Conv2d(f, f, kernel_size=3, stride=2, padding=1))
    return nn.Sequential(*layers)


class ResidualConvUnit(nn.Module):  # DPT/LSeg ResidualConvUnit_custom with bn=True
    def __init__(self, features):
        super().__init__()
        self.conv1 = nn.Conv2d(features, features, 3, padding=1, bias=False)
        self.bn1 = nn.BatchNorm2d(features)
        self.conv2 = nn.Conv2d(features, features, 3, padding=1, bias=False)
        self.bn2 = nn.BatchNorm2d(features)

    def forward(self, x):
        out = self.bn1(self.conv1(F.relu(x)))
        out = self.bn2(self.conv2(F.relu(out)))
        return out + x


class FeatureFusionBlock(nn.Module):  # DPT/LSeg FeatureFusionBlock_custom
    def __init__(self, features):
        super().__init__()
        self.resConfUnit1 = ResidualConvUnit(features)
        self.resConfUnit2 = ResidualConvUnit(features)
        self.out_conv = nn.Conv2d(features, features, 1)

    def forward(self, *xs):
        output = xs[0]
        if len(xs) == 2:
            output = output + self.resConfUnit1(xs[1])
        output = self.resConfUnit2(output)
        output = F.interpolate(output, scale_factor=2, mode="bilinear", align_corners=True)
        return self.out_conv(output)


class TinyLSegNet(nn.Module):
    """The attributes export_lseg.LSegPixelEncoder reads from a real LSegNet: pretrained, scratch."""

    def __init__(self, cfg):
        super().__init__()
        self.pretrained = nn.Module()
        self.pretrained.model = VisionTransformer(cfg)
        self.pretrained.model.norm = nn.LayerNorm(cfg["vit_width"], eps=1e-6)
        self.pretrained.hooks = cfg["hooks"]
        for i in range(4):
            setattr(self.pretrained, f"act_postprocess{i + 1}", reassemble(cfg, i))
        f = cfg["features"]
        self.scratch = nn.Module()
        for i in range(4):
            setattr(self.scratch, f"layer{i + 1}_rn", nn.Conv2d(cfg["reassemble"][i], f, 3, padding=1, bias=False))
            setattr(self.scratch, f"refinenet{i + 1}", FeatureFusionBlock(f))
        self.scratch.head1 = nn.Conv2d(f, cfg["out_dim"], kernel_size=1)
        for m in self.modules():  # trained BN statistics are not identity; make the stand-in's not either
            if isinstance(m, nn.BatchNorm2d):
                m.running_mean.uniform_(-0.1, 0.1)
                m.running_var.uniform_(0.5, 1.5)


def tiny_forward_vit(pretrained, x):
    """LSeg's forward_vit for the stand-in: the outputs of the 4 tapped blocks, reassembled."""
    vit = pretrained.model
    x = vit.patch_embed.proj(x).flatten(2).transpose(1, 2)
    x = torch.cat((vit.cls_token.expand(x.shape[0], -1, -1), x), dim=1) + vit.pos_embed
    taps = []
    for i, block in enumerate(vit.blocks):
        x = block(x)
        if i in pretrained.hooks:
            taps.append(x)
    return tuple(getattr(pretrained, f"act_postprocess{i + 1}")(t) for i, t in enumerate(taps))


# ---------------------------------------------------------------- CLIP-shaped encoders
class ResidualAttentionBlock(nn.Module):  # CLIP's block (sequence-first)
    def __init__(self, d, heads):
        super().__init__()
        self.attn = nn.MultiheadAttention(d, heads)
        self.ln_1 = nn.LayerNorm(d)
        self.mlp = nn.Sequential(nn.Linear(d, 4 * d), nn.GELU(), nn.Linear(4 * d, d))
        self.ln_2 = nn.LayerNorm(d)

    def forward(self, x, mask=None):
        y = self.ln_1(x)
        x = x + self.attn(y, y, y, need_weights=False, attn_mask=mask)[0]
        return x + self.mlp(self.ln_2(x))


class TinyClip(nn.Module):
    """CLIP's encode_text / encode_image with CLIP's parameter layout, at toy size."""

    def __init__(self, cfg):
        super().__init__()
        w, n = cfg["text_width"], cfg["context_length"]
        self.token_embedding = nn.Embedding(cfg["vocab_size"], w)
        self.positional_embedding = nn.Parameter(0.01 * torch.randn(n, w))
        self.text_blocks = nn.ModuleList(
            [ResidualAttentionBlock(w, cfg["text_heads"]) for _ in range(cfg["text_layers"])])
        self.ln_final = nn.LayerNorm(w)
        self.text_projection = nn.Parameter(w ** -0.5 * torch.randn(w, cfg["embed_dim"]))
        self.register_buffer("causal_mask", torch.full((n, n), float("-inf")).triu_(1))
        vw, p, s = cfg["vision_width"], cfg["patch"], cfg["image_size"]
        self.conv1 = nn.Conv2d(3, vw, kernel_size=p, stride=p, bias=False)
        self.class_embedding = nn.Parameter(vw ** -0.5 * torch.randn(vw))
        self.visual_positional_embedding = nn.Parameter(vw ** -0.5 * torch.randn((s // p) ** 2 + 1, vw))
        self.ln_pre = nn.LayerNorm(vw)
        self.visual_blocks = nn.ModuleList(
            [ResidualAttentionBlock(vw, cfg["vision_heads"]) for _ in range(cfg["vision_layers"])])
        self.ln_post = nn.LayerNorm(vw)
        self.proj = nn.Parameter(vw ** -0.5 * torch.randn(vw, cfg["embed_dim"]))

    def encode_text(self, text):
        x = self.token_embedding(text) + self.positional_embedding
        x = x.permute(1, 0, 2)
        for block in self.text_blocks:
            x = block(x, self.causal_mask)
        x = self.ln_final(x.permute(1, 0, 2))
        return x[torch.arange(x.shape[0]), text.argmax(dim=-1)] @ self.text_projection

    def encode_image(self, image):
        x = self.conv1(image)
        x = x.reshape(x.shape[0], x.shape[1], -1).permute(0, 2, 1)
        cls = self.class_embedding + torch.zeros(x.shape[0], 1, x.shape[-1], dtype=x.dtype)
        x = self.ln_pre(torch.cat([cls, x], dim=1) + self.visual_positional_embedding)
        x = x.permute(1, 0, 2)
        for block in self.visual_blocks:
            x = block(x)
        return self.ln_post(x.permute(1, 0, 2)[:, 0, :]) @ self.proj


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
    export_lseg.write_json(os.path.join(out, "throwing.json"), throwing)


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
