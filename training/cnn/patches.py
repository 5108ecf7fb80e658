#!/usr/bin/python3
"""The compact patch set: what train.py needs of the n2n dataset in one float16 .npz small
enough to carry to a GPU machine (~60 MiB), or to train from without the EXRs.

    /usr/bin/python3 training/cnn/patches.py                       # -> $CACHE/cnn/patches.npz
    /usr/bin/python3 training/cnn/patches.py --size 48 --max-mib 60 --out FILE

One patch per (training crop, level): the crop's levels take turns (crop i gives level
i % 3 first; --per-crop 2 or 3 takes more of its levels while the size allows), its centre
drawn from train.py's §5.1 PDF (noisy and detailed regions first). Depth is scaled over the
whole crop before cutting (model.scale_depth), as the op does over the frame. Channels
(PLANES, [N, C, P, P] float16, finite, |x| <= 65000): the raw planes of model.py, with the
albedo and normal variances kept as their mean over RGB (all the network reads of them), and
the target's colour and diffuse (an independent render: Noise2Noise, train.py).
Crops of the validation and test families (train.HELD_OUT) are never in it; --split val makes
the validation families' set instead (train.py --val-patches).
"""
import argparse
import os
import random
import sys

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import train  # noqa: E402

# (name, channels) in file order
PLANES = [("color", 3), ("color_var", 3), ("diffuse", 3), ("diffuse_var", 3), ("specular_var", 3),
          ("demod", 3), ("albedo", 3), ("albedo_var", 1), ("normal", 3), ("normal_var", 1),
          ("depth", 1), ("depth_var", 1), ("target_color", 3), ("target_diffuse", 3)]
F16_MAX = 65000.0


def cut(prefix, spp, size, rng):
    raw, ref, _, pdf = train.load(prefix, spp)
    h, w = pdf.shape
    idx = int(torch.multinomial(pdf.flatten(), 1, generator=rng))
    cy, cx = idx // w, idx % w
    y0 = min(max(cy - size // 2, 0), h - size)
    x0 = min(max(cx - size // 2, 0), w - size)
    planes = dict(raw)
    planes["albedo_var"] = raw["albedo_var"].mean(0, keepdim=True)
    planes["normal_var"] = raw["normal_var"].mean(0, keepdim=True)
    planes["target_color"], planes["target_diffuse"] = ref[0], ref[1]
    stack = torch.cat([planes[n][:, y0:y0 + size, x0:x0 + size] for n, _ in PLANES])
    stack = torch.clamp(torch.nan_to_num(stack, nan=0.0, posinf=F16_MAX, neginf=-F16_MAX), -F16_MAX, F16_MAX)
    return stack.numpy().astype(np.float16)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(train.CACHE, "cnn", "patches.npz"))
    ap.add_argument("--size", type=int, default=48)
    ap.add_argument("--per-crop", type=int, default=3, help="levels per crop at most")
    ap.add_argument("--max-mib", type=float, default=60)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--split", choices=("train", "val"), default="train",
                    help="val: patches of the validation families (at 16 and 64 spp), for "
                         "train.py --val-patches where the crops are not at hand")
    args = ap.parse_args()
    train_files, val_files = train.list_files()
    files = train_files if args.split == "train" else val_files
    by_crop = {}
    for prefix, spp in files:
        by_crop.setdefault(prefix, []).append(spp)
    crops = sorted(by_crop)
    channels = sum(c for _, c in PLANES)
    per_patch = channels * args.size * args.size * 2
    budget = int(args.max_mib * 2 ** 20 / per_patch / 0.5)  # zip halves them (measured)
    order = []
    for turn in range(args.per_crop):
        for i, prefix in enumerate(crops):
            levels = sorted(by_crop[prefix])
            if turn < len(levels):
                order.append((prefix, levels[(i + turn) % len(levels)]))
    order = order[:budget]
    rng = torch.Generator().manual_seed(args.seed)
    random.seed(args.seed)
    patches = np.stack([cut(prefix, spp, args.size, rng) for prefix, spp in order])
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    tmp = args.out + ".tmp.npz"
    while True:  # fewer patches until the compressed file fits
        n = len(order)
        np.savez_compressed(tmp, patches=patches[:n], spp=np.array([s for _, s in order], np.int16),
                            crop=np.array([os.path.basename(p) for p, _ in order]),
                            planes=np.array(["%s:%d" % p for p in PLANES]))
        mib = os.path.getsize(tmp) / 2 ** 20
        if mib <= args.max_mib:
            break
        order = order[:int(n * args.max_mib / mib * 0.98)]
    os.replace(tmp, args.out)
    print("%s: %d patches of %d^2 from %d crops, %.1f MiB" % (
        args.out, len(order), args.size, len(crops), os.path.getsize(args.out) / 2 ** 20))


if __name__ == "__main__":
    main()
