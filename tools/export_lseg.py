#!/usr/bin/env python3
"""Export LSeg's pixel-embedding network as TorchScript + slamvdb model manifest.

For users who HAVE the upstream LSeg code and a checkpoint (https://github.com/isl-org/lang-seg,
e.g. demo_e200.ckpt). Writes, into --out:
  lseg_dense.pt / lseg_dense.json   image (N x 3 x H x W, normalised) -> N x 512 x H/2 x W/2 unit vectors
  lseg_text.pt  / lseg_text.json    LSeg's CLIP ViT-B/32 text encoder (N x 77 int64 tokens -> N x 512)
  bpe_simple_vocab_16e6.txt.gz      CLIP's merge list, copied from the installed `clip` package

The exported network is LSeg up to and including `scratch.head1` followed by the per-pixel L2
normalisation LSeg applies before comparing with text; the final x2 upsampling is left out, so a
256 x 384 input gives the paper's 128 x 192 feature map. Resizing is NOT part of the network:
slamvdb resizes in C++ as the manifest says.

  python3 tools/export_lseg.py --lseg-repo ~/lang-seg --checkpoint demo_e200.ckpt --out models/

--random-init-test runs the same wrapping, tracing, checking and manifest writing on a randomly
initialised LSeg-shaped stand-in (tools/stand_in_networks.py) so this script is exercised without
the real weights. Its outputs are meaningless as embeddings.
"""
import argparse
import os
import shutil
import sys

import torch
import torch.nn as nn

from export_clip import export_text
from export_common import add_common_arguments, trace_checked, write_json

LSEG_MEAN = [0.5, 0.5, 0.5]  # LSegModule's norm_mean / norm_std
LSEG_STD = [0.5, 0.5, 0.5]


class LSegPixelEncoder(nn.Module):
    """LSeg's forward() up to the per-pixel image features, without text or upsampling.

    `forward_vit(pretrained, x) -> (layer_1, layer_2, layer_3, layer_4)` is LSeg's backbone
    function; it is passed in so the same head code runs on the real network and the stand-in.
    """

    def __init__(self, net, forward_vit):
        super().__init__()
        self.net = net
        self.forward_vit = forward_vit

    def forward(self, x):
        layer_1, layer_2, layer_3, layer_4 = self.forward_vit(self.net.pretrained, x)
        s = self.net.scratch
        path_4 = s.refinenet4(s.layer4_rn(layer_4))
        path_3 = s.refinenet3(path_4, s.layer3_rn(layer_3))
        path_2 = s.refinenet2(path_3, s.layer2_rn(layer_2))
        path_1 = s.refinenet1(path_2, s.layer1_rn(layer_1))
        features = s.head1(path_1)
        return features / features.norm(dim=1, keepdim=True)


def dense_manifest(model_id, height, width, dim, threads=0):
    return {
        "manifest_version": 1,
        "kind": "dense_image",
        "model_id": model_id,
        "input": {
            "height": height,
            "width": width,
            "resize": "resize",
            # Camera images are several times larger than the network input; area averaging
            # is the alias-free way to shrink them.
            "interpolation": "area",
            "channel_order": "RGB",
            "value_scale": 1.0 / 255.0,
            "mean": LSEG_MEAN,
            "std": LSEG_STD,
        },
        "output": {
            "dim": dim,
            "height": height // 2,
            "width": width // 2,
            "layout": "CHW",
            "l2_normalized": True,
            "normalize_output": False,
        },
        "runtime": {"threads": threads, "batch_size": 1},
    }


def export_dense(net, forward_vit, out_dir, name, model_id, height, width, threads=0):
    """Writes NAME.pt + NAME.json for LSeg-shaped `net`; returns the manifest."""
    if height % 32 or width % 32:
        raise SystemExit(f"input {height} x {width}: LSeg needs both sides to be multiples of 32")
    encoder = LSegPixelEncoder(net, forward_vit)
    example = torch.randn(1, 3, height, width)
    out = trace_checked(encoder, example, os.path.join(out_dir, name + ".pt"))
    if out.shape[2:] != (height // 2, width // 2):
        raise SystemExit(f"LSeg features are {tuple(out.shape)}, expected H/2 x W/2")
    manifest = dense_manifest(model_id, height, width, int(out.shape[1]), threads)
    write_json(os.path.join(out_dir, name + ".json"), manifest)
    return manifest


def load_upstream(lseg_repo, checkpoint, backbone):
    """Builds LSegNet from the lang-seg sources and loads the checkpoint's `net.*` weights on CPU."""
    import clip

    # lang-seg calls clip.load(..., device='cuda') while building the network; keep it on CPU.
    clip_load = clip.load
    clip.load = lambda name, device="cpu", jit=False, **kw: clip_load(name, device="cpu", jit=False, **kw)
    sys.path.insert(0, os.path.abspath(lseg_repo))
    from modules.models.lseg_net import LSegNet
    from modules.models.lseg_vit import forward_vit

    net = LSegNet(labels=["other"], backbone=backbone, features=256, crop_size=480, arch_option=0,
                  block_depth=0, activation="lrelu")
    state = torch.load(checkpoint, map_location="cpu")
    state = state.get("state_dict", state)
    weights = {k[len("net."):]: v for k, v in state.items() if k.startswith("net.")}
    missing, unexpected = net.load_state_dict(weights, strict=False)
    missing = [k for k in missing if not k.startswith("clip_pretrained.")]
    if missing:
        raise SystemExit(f"{checkpoint}: {len(missing)} LSeg weights missing, e.g. {missing[:3]}")
    if unexpected:
        print(f"note: {len(unexpected)} checkpoint entries unused, e.g. {unexpected[:3]}")
    return net.float().eval(), forward_vit


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True, help="output directory")
    p.add_argument("--lseg-repo", help="checkout of https://github.com/isl-org/lang-seg")
    p.add_argument("--checkpoint", help="LSeg checkpoint (.ckpt)")
    p.add_argument("--backbone", default="clip_vitl16_384")
    p.add_argument("--height", type=int, default=256)
    p.add_argument("--width", type=int, default=384)
    add_common_arguments(p)
    args = p.parse_args()
    os.makedirs(args.out, exist_ok=True)

    if args.random_init_test:
        import stand_in_networks as sn

        torch.manual_seed(0)
        net, forward_vit = sn.TinyLSegNet(sn.TINY_LSEG), sn.tiny_forward_vit
        clip_model = sn.TinyClip(sn.TINY_CLIP)
        if not args.vocab:
            raise SystemExit("--random-init-test needs --vocab (the CLIP merge list)")
        vocab = os.path.abspath(args.vocab)
        height, width, model_id = sn.TINY_LSEG["height"], sn.TINY_LSEG["width"], "lseg-random-init-test"
    else:
        if not args.lseg_repo or not args.checkpoint:
            raise SystemExit("need --lseg-repo and --checkpoint (or --random-init-test)")
        net, forward_vit = load_upstream(args.lseg_repo, args.checkpoint, args.backbone)
        clip_model = net.clip_pretrained.float()
        import clip

        source = args.vocab or os.path.join(os.path.dirname(clip.__file__), "bpe_simple_vocab_16e6.txt.gz")
        vocab = os.path.basename(source)
        shutil.copyfile(source, os.path.join(args.out, vocab))
        height, width = args.height, args.width
        model_id = f"lseg-{args.backbone}-{os.path.splitext(os.path.basename(args.checkpoint))[0]}"

    dense = export_dense(net, forward_vit, args.out, "lseg_dense", model_id, height, width, args.threads)
    # LSeg compares unit image features with unit text features.
    text = export_text(clip_model, args.out, "lseg_text", model_id + "-text", vocab, normalize=True,
                       threads=args.threads)
    if text["output"]["dim"] != dense["output"]["dim"]:
        raise SystemExit(f"text dim {text['output']['dim']} != pixel dim {dense['output']['dim']}")
    print(f"wrote {args.out}/lseg_dense.pt (+.json) and lseg_text.pt (+.json), dim {dense['output']['dim']}")


if __name__ == "__main__":
    main()
