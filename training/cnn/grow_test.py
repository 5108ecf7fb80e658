#!/usr/bin/python3
"""model.grow computes the same function as the model it grows (ctest cnn_grow; needs PyTorch,
.ci/install-deps --training: skipped with 77 without it).

Grows the committed kpcn_can.mcdnw deeper, wider and both, in float64, and checks the
outputs on random planes are those of the original exactly; checks what cannot be grown is
refused and the FLOP count of the shipped widths is unchanged."""
import os
import sys

try:
    import torch
except ImportError:
    print("SKIP: no PyTorch (.ci/install-deps --training)")
    sys.exit(77)

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "training", "common"))
import model as kpcn  # noqa: E402
from weights import read_weights  # noqa: E402

PLANES = {"color": 3, "color_var": 3, "diffuse": 3, "diffuse_var": 3, "specular": 3,
          "specular_var": 3, "demod": 3, "albedo": 3, "albedo_var": 3, "normal": 3,
          "normal_var": 3, "depth": 1, "depth_var": 1}


def outputs(state_dict, raw):
    net = kpcn.KPCN(kpcn.widths_of(state_dict)).double()
    net.load_state_dict({k: v.double() for k, v in state_dict.items()})
    with torch.no_grad():
        return net(raw)


def main():
    _, tensors = read_weights(os.path.join(ROOT, "models", "kpcn_can.mcdnw"))
    start = {k: torch.from_numpy(v.copy()) for k, v in tensors.items()}
    assert kpcn.widths_of(start) == (16, 32, 48), kpcn.widths_of(start)
    assert round(kpcn.flops_per_pixel((16, 32, 48))) == 51118, kpcn.flops_per_pixel((16, 32, 48))
    torch.manual_seed(3)
    raw = {k: torch.rand(2, c, 64, 64, dtype=torch.float64) * 4 for k, c in PLANES.items()}
    raw["specular"] = raw["color"] - raw["diffuse"]
    want = outputs(start, raw)
    failed = 0
    for widths in ((16, 32, 48, 64), (16, 32, 48, 64, 80), (32, 64, 96), (32, 64, 96, 128)):
        grown = kpcn.grow(start, widths)
        got = outputs(grown, raw)
        diff = max(float((a - b).abs().max()) for a, b in zip(want, got))
        moved = sum(int(k not in start or v.shape != start[k].shape) for k, v in grown.items())
        ok = kpcn.widths_of(grown) == widths and diff == 0 and moved > 0
        print("%s %s: max difference %g, %d tensors new or resized" % (
            "ok  " if ok else "FAIL", widths, diff, moved))
        failed += not ok
    for widths in ((8, 32, 48), (16, 32)):
        try:
            kpcn.grow(start, widths)
            print("FAIL %s: grown, should be refused" % (widths,))
            failed += 1
        except ValueError as e:
            print("ok   %s refused: %s" % (widths, e))
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
