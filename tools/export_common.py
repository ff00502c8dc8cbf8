"""What every model-export script shares: tracing with a check, writing a manifest, common options.

Imports no other tool; export_clip.py, export_lseg.py and make_test_models.py import it.
"""
import json

import torch


def trace_checked(module, example, path):
    """Traces `module` on `example`, saves it and checks the reloaded file reproduces eager mode."""
    module = module.eval()
    with torch.no_grad():
        expected = module(example)
        traced = torch.jit.trace(module, example, check_trace=False)
        traced.save(path)
        reloaded = torch.jit.load(path)
        got = reloaded(example)
    if got.shape != expected.shape or not torch.allclose(got, expected, atol=1e-4, rtol=1e-4):
        raise SystemExit(f"{path}: the traced model does not reproduce the eager model")
    return expected


def write_json(path, manifest):
    with open(path, "w") as f:
        json.dump(manifest, f, indent=2)
        f.write("\n")


def add_common_arguments(p):
    """The options every export script shares."""
    p.add_argument("--vocab", help="CLIP merge list (default: the one shipped in the clip package)")
    p.add_argument("--threads", type=int, default=0,
                   help="runtime.threads in the manifests; 0 = libtorch's default (one per physical core)")
    p.add_argument("--random-init-test", action="store_true",
                   help="export a small randomly initialised stand-in instead (exercises this script)")
