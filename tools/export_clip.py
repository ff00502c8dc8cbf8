#!/usr/bin/env python3
"""Export a CLIP model's text and image encoders as TorchScript + slamvdb model manifests.

For users who HAVE OpenAI's `clip` package and its weights (https://github.com/openai/CLIP).
Writes, into --out:
  clip_text.pt  / clip_text.json    N x 77 int64 tokens -> N x D (model.encode_text)
  clip_image.pt / clip_image.json   N x 3 x S x S normalised image -> N x D (model.encode_image)
  bpe_simple_vocab_16e6.txt.gz      the merge list the C++ tokenizer reads, copied from the package

Pre-processing is not part of the networks: slamvdb does CLIP's resize-short-side + centre crop,
scaling and mean/std in C++ as the manifest says (OpenCV bicubic, close to but not bit-identical
with PIL's bicubic).

  python3 tools/export_clip.py --model ViT-B/32 --out models/

--random-init-test runs the same wrapping, tracing, checking and manifest writing on a randomly
initialised CLIP-shaped stand-in (tools/stand_in_networks.py) so this script is exercised without
the real weights. Its outputs are meaningless as embeddings.
"""
import argparse
import os
import shutil

import torch
import torch.nn as nn

from export_common import add_common_arguments, trace_checked, write_json

CLIP_MEAN = [0.48145466, 0.4578275, 0.40821073]
CLIP_STD = [0.26862954, 0.26130258, 0.27577711]
CONTEXT_LENGTH = 77


class ClipTextEncoder(nn.Module):
    def __init__(self, model):
        super().__init__()
        self.model = model

    def forward(self, tokens):
        return self.model.encode_text(tokens)


class ClipImageEncoder(nn.Module):
    def __init__(self, model):
        super().__init__()
        self.model = model

    def forward(self, image):
        return self.model.encode_image(image)


def text_manifest(model_id, dim, vocab, normalize, threads=0):
    return {
        "manifest_version": 1,
        "kind": "text",
        "model_id": model_id,
        "text": {"context_length": CONTEXT_LENGTH, "vocab": vocab},
        "output": {"dim": dim, "l2_normalized": False, "normalize_output": normalize},
        "runtime": {"threads": threads, "batch_size": 1},
    }


def image_manifest(model_id, size, dim, threads=0):
    return {
        "manifest_version": 1,
        "kind": "image",
        "model_id": model_id,
        "input": {
            "height": size,
            "width": size,
            "resize": "resize_short_center_crop",
            "interpolation": "bicubic",
            "channel_order": "RGB",
            "value_scale": 1.0 / 255.0,
            "mean": CLIP_MEAN,
            "std": CLIP_STD,
        },
        "output": {"dim": dim, "l2_normalized": False, "normalize_output": True},
        "runtime": {"threads": threads, "batch_size": 1},
    }


def example_tokens():
    """start, a few words, end, zero padding: the shape and value range of real tokens."""
    tokens = torch.zeros(1, CONTEXT_LENGTH, dtype=torch.long)
    tokens[0, :5] = torch.tensor([49406, 320, 1125, 539, 49407])
    return tokens


def export_text(model, out_dir, name, model_id, vocab, normalize, threads=0):
    """Writes NAME.pt + NAME.json for a model with CLIP's encode_text; returns the manifest."""
    out = trace_checked(ClipTextEncoder(model), example_tokens(), os.path.join(out_dir, name + ".pt"))
    manifest = text_manifest(model_id, int(out.shape[1]), vocab, normalize, threads)
    write_json(os.path.join(out_dir, name + ".json"), manifest)
    return manifest


def export_image(model, out_dir, name, model_id, size, threads=0):
    """Writes NAME.pt + NAME.json for a model with CLIP's encode_image; returns the manifest."""
    example = torch.randn(1, 3, size, size)
    out = trace_checked(ClipImageEncoder(model), example, os.path.join(out_dir, name + ".pt"))
    manifest = image_manifest(model_id, size, int(out.shape[1]), threads)
    write_json(os.path.join(out_dir, name + ".json"), manifest)
    return manifest


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--model", default="ViT-B/32", help="name or checkpoint for clip.load")
    add_common_arguments(p)
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)

    if args.random_init_test:
        import stand_in_networks as sn

        torch.manual_seed(0)
        model = sn.TinyClip(sn.TINY_CLIP)
        if not args.vocab:
            raise SystemExit("--random-init-test needs --vocab (the CLIP merge list)")
        vocab = os.path.abspath(args.vocab)
        size, model_id = sn.TINY_CLIP["image_size"], "clip-random-init-test"
    else:
        import clip

        model, _ = clip.load(args.model, device="cpu", jit=False)
        model = model.float().eval()
        source = args.vocab or os.path.join(os.path.dirname(clip.__file__), "bpe_simple_vocab_16e6.txt.gz")
        vocab = os.path.basename(source)
        shutil.copyfile(source, os.path.join(args.out, vocab))
        size = model.visual.input_resolution
        model_id = "clip-" + args.model.replace("/", "-")

    text = export_text(model, args.out, "clip_text", model_id + "-text", vocab, normalize=True, threads=args.threads)
    image = export_image(model, args.out, "clip_image", model_id + "-image", size, args.threads)
    print(f"wrote {args.out}/clip_text.pt (+.json, dim {text['output']['dim']}) and "
          f"clip_image.pt (+.json, {size} x {size} -> {image['output']['dim']})")


if __name__ == "__main__":
    main()
