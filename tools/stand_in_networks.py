"""Randomly initialised stand-ins for the paper's networks (their outputs mean nothing).

The real LSeg / CLIP weights are not available here, so the export scripts (--random-init-test)
and the C++ TorchScript backend's tests use modules with the SAME interfaces and structure:
  - TinyLSegNet: LSeg's structure (ViT with 4 tapped blocks, DPT reassemble + fusion blocks,
    head1 to the embedding dim), read by export_lseg.LSegPixelEncoder through tiny_forward_vit:
    N x 3 x H x W -> N x C x H/2 x W/2.
  - TinyClip: CLIP's encode_text (token + position embedding, causal transformer, feature at the
    end-of-text token = argmax id, projection) and encode_image (ViT, class token, projection).
TINY_* are the test sizes, VIT_B16_LSEG a ViT-B/16-sized LSeg for the benchmark.
Imports no other tool: the export scripts and make_test_models.py import it.
"""
import torch
import torch.nn as nn
import torch.nn.functional as F

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
