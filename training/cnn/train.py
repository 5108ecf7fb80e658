#!/usr/bin/python3
"""Trains the CPU KPCN (model.py) on the generated Cycles crops (training/datagen).

    nice -n 10 /usr/bin/python3 training/cnn/train.py --minutes 35          # fresh run
    nice -n 10 /usr/bin/python3 training/cnn/train.py --resume --minutes 60 # continue

Data: $CACHE/datasets/{full,small}/<crop>/<crop>_00NNspp{,_var}.exr and <crop>_ref.exr,
levels 4/16/64/256 ($CACHE = $MCDN_CACHE or ~/.cache/mcdenoise). Validation: the `full`
crops whose number % 6 == 4 (the split of training/mix), whole crops at 16 and 64 spp;
never ../shared/data (the evaluation set). New crops are picked up at every validation.

Patches (§5.1): 64x64, centres drawn from a PDF over the crop that favours noisy and
detailed regions: 0.2 + relative colour variance + normal-gradient magnitude (each scaled
to mean 1), so flat regions are still seen. Augmentation: the 8 flips/transposes (normals
rotated with the image) and an exposure scale 2^U(-2, 2) of every radiance plane (variances
by its square). Loss (§5.2, §7): L1, in the log(1 + x) domain of the diffuse and specular
components and of the recombined colour (eq. 4). Adam.

Run state in $CACHE/cnn/run/: checkpoint.pt (model, optimizer, step, elapsed, curve; written
every 50 steps and at the end), loss.csv (step, minutes, train loss, validation relMSE).
"""
import argparse
import csv
import json
import math
import os
import random
import re
import signal
import sys
import time

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import data  # noqa: E402
import model as kpcn  # noqa: E402

CACHE = os.environ.get("MCDN_CACHE", os.path.expanduser("~/.cache/mcdenoise"))
RUN = os.path.join(CACHE, "cnn", "run")
LEVELS = (4, 16, 64, 256)
VAL_LEVELS = (16, 64)
RADIANCE = ("color", "diffuse", "specular")


def is_validation(crop_dir):
    m = re.match(r"(\d+)_", os.path.basename(crop_dir))
    return "/full/" in crop_dir and m is not None and int(m.group(1)) % 6 == 4


def list_files():
    train, val = [], []
    for dataset in ("full", "small"):
        for crop in data.crops(os.path.join(CACHE, "datasets", dataset)):
            name = os.path.basename(crop)
            for spp in LEVELS:
                prefix = os.path.join(crop, name)
                if not os.path.exists("%s_%04dspp_var.exr" % (prefix, spp)):
                    continue
                if is_validation(crop):
                    if spp in VAL_LEVELS:
                        val.append((prefix, spp))
                else:
                    train.append((prefix, spp))
    return train, val


_cache = {}


def load(prefix, spp):
    """Raw planes as torch tensors [C, H, W] (depth scaled), references, patch PDF."""
    key = (prefix, spp)
    if key in _cache:
        return _cache[key]
    raw = {k: torch.from_numpy(v) for k, v in data.load_render(prefix, spp).items()}
    raw["depth"], raw["depth_var"] = kpcn.scale_depth(raw["depth"], raw["depth_var"])
    ref = [torch.from_numpy(np.ascontiguousarray(r)) for r in data.load_reference(prefix + "_ref.exr")]
    # §5.1 patch PDF: noisy (relative colour variance) and detailed (normal gradients) regions.
    rel_var = (raw["color_var"] / (raw["color"] ** 2 + 1e-2)).mean(0)
    gx = torch.zeros_like(raw["normal"])
    gy = torch.zeros_like(raw["normal"])
    gx[:, :, :-1] = raw["normal"][:, :, 1:] - raw["normal"][:, :, :-1]
    gy[:, :-1, :] = raw["normal"][:, 1:, :] - raw["normal"][:, :-1, :]
    detail = (gx.abs() + gy.abs()).sum(0)
    pdf = 0.2 + rel_var / (rel_var.mean() + 1e-8) + detail / (detail.mean() + 1e-8)
    _cache[key] = (raw, ref, torch.nan_to_num(pdf))
    return _cache[key]


def transform(t, k, flip, is_normal=False):
    """Rotation by k*90 degrees and an optional flip of [C, H, W]; normals (camera space,
    x right, y up) rotated with the image."""
    if flip:
        t = torch.flip(t, [2])
        if is_normal:
            t = t * torch.tensor([-1.0, 1.0, 1.0]).view(3, 1, 1)
    for _ in range(k):
        t = torch.rot90(t, 1, [1, 2])  # counter-clockwise on screen
        if is_normal:
            t = torch.stack([-t[1], t[0], t[2]])  # (x, y) -> (-y, x)
    return t


def sample_batch(files, batch, patch):
    raws = {}
    refs = []
    for _ in range(batch):
        prefix, spp = random.choice(files)
        raw, ref, pdf = load(prefix, spp)
        h, w = pdf.shape
        size = min(patch, h, w) // 4 * 4
        # centre drawn from the PDF, then clamped so the patch fits
        idx = int(torch.multinomial(pdf.flatten(), 1))
        cy, cx = idx // w, idx % w
        y0 = min(max(cy - size // 2, 0), h - size)
        x0 = min(max(cx - size // 2, 0), w - size)
        k, flip = random.randrange(4), random.random() < 0.5
        exposure = 2.0 ** random.uniform(-2, 2)
        crop = lambda t: t[:, y0:y0 + size, x0:x0 + size]  # noqa: E731
        for name, t in raw.items():
            t = transform(crop(t), k, flip, name == "normal")
            if name in RADIANCE:
                t = t * exposure
            elif name in ("color_var", "diffuse_var", "specular_var"):
                t = t * exposure ** 2
            raws.setdefault(name, []).append(t)
        refs.append([transform(crop(r), k, flip) * exposure for r in ref])
        if size != patch:  # small crops: use every patch at the smallest size
            patch = size
    raws = {n: torch.stack([t[..., :patch, :patch] for t in v]) for n, v in raws.items()}
    ref = [torch.stack([r[i][..., :patch, :patch] for r in refs]) for i in range(3)]
    return raws, ref


def loss_fn(out, ref):
    diffuse, specular, colour = out
    ref_colour, ref_diffuse, ref_specular = ref
    l1 = lambda a, b: (torch.log1p(torch.relu(a)) - torch.log1p(torch.relu(b))).abs().mean()  # noqa: E731
    return l1(diffuse, ref_diffuse) + l1(specular, ref_specular) + l1(colour, ref_colour)


def relmse(image, reference):
    return float(((image - reference) ** 2 / (reference ** 2 + 0.01)).mean())


def validate(net, files):
    """Mean relMSE of the denoised colour and of the noisy input over whole validation crops."""
    if not files:
        return float("nan"), float("nan")
    net.eval()
    errors, noisy = [], []
    with torch.no_grad():
        for prefix, spp in files:
            raw, ref, _ = load(prefix, spp)
            h, w = raw["color"].shape[1:]
            h4, w4 = h // 4 * 4, w // 4 * 4
            batch = {k: v[None, :, :h4, :w4] for k, v in raw.items()}
            _, _, colour = net(batch)
            errors.append(relmse(colour[0], ref[0][:, :h4, :w4]))
            noisy.append(relmse(raw["color"][:, :h4, :w4], ref[0][:, :h4, :w4]))
    net.train()
    return float(np.mean(errors)), float(np.mean(noisy))


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--resume", action="store_true", help="continue from $CACHE/cnn/run/checkpoint.pt")
    ap.add_argument("--minutes", type=float, default=35, help="wall-clock budget of this session")
    ap.add_argument("--steps", type=int, default=0, help="stop at this total step (0: no limit)")
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--patch", type=int, default=64)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--validate-every", type=int, default=200)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    os.makedirs(RUN, exist_ok=True)
    checkpoint_path = os.path.join(RUN, "checkpoint.pt")

    net = kpcn.KPCN()
    opt = torch.optim.Adam(net.parameters(), lr=args.lr)
    state = {"step": 0, "elapsed": 0.0, "curve": [], "args": vars(args)}
    if args.resume and os.path.exists(checkpoint_path):
        ck = torch.load(checkpoint_path)
        net.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        state = ck["state"]
        print("resumed at step %d (%.1f min trained)" % (state["step"], state["elapsed"] / 60), flush=True)
    elif os.path.exists(checkpoint_path) and not args.resume:
        sys.exit("%s exists: pass --resume to continue it, or remove it to start over" % checkpoint_path)
    for g in opt.param_groups:
        g["lr"] = args.lr
    random.seed(args.seed + state["step"])
    torch.manual_seed(args.seed + state["step"])

    stop = {"now": False}
    signal.signal(signal.SIGTERM, lambda *a: stop.update(now=True))
    signal.signal(signal.SIGINT, lambda *a: stop.update(now=True))

    def save():
        tmp = checkpoint_path + ".tmp"
        torch.save({"model": net.state_dict(), "optimizer": opt.state_dict(), "state": state}, tmp)
        os.replace(tmp, checkpoint_path)
        with open(os.path.join(RUN, "loss.csv"), "w", newline="") as f:
            wr = csv.writer(f)
            wr.writerow(["step", "minutes", "train_loss", "val_relmse", "val_noisy_relmse", "train_files"])
            for row in state["curve"]:
                wr.writerow(row)

    train_files, val_files = list_files()
    print("train files %d, validation files %d" % (len(train_files), len(val_files)), flush=True)
    start = time.time()
    elapsed0 = state["elapsed"]
    running = []
    while not stop["now"]:
        if args.steps and state["step"] >= args.steps:
            break
        if time.time() - start > args.minutes * 60:
            break
        raws, ref = sample_batch(train_files, args.batch, args.patch)
        loss = loss_fn(net(raws), ref)
        opt.zero_grad()
        loss.backward()
        torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
        opt.step()
        state["step"] += 1
        state["elapsed"] = elapsed0 + time.time() - start
        running.append(float(loss))
        if state["step"] % 50 == 0:
            print("step %d  %.1f min  loss %.4f" % (state["step"], state["elapsed"] / 60, np.mean(running[-50:])), flush=True)
            if state["step"] % args.validate_every == 0:
                train_files, val_files = list_files()
                v, vn = validate(net, val_files)
                state["curve"].append([state["step"], round(state["elapsed"] / 60, 2),
                                       round(float(np.mean(running[-50:])), 5), v, vn, len(train_files)])
                print("  validation relMSE %.5f (noisy %.5f), %d train files" % (v, vn, len(train_files)), flush=True)
            save()
    v, vn = validate(net, val_files)
    state["curve"].append([state["step"], round(state["elapsed"] / 60, 2),
                           round(float(np.mean(running[-50:] or [float("nan")])), 5), v, vn, len(train_files)])
    print("final step %d: validation relMSE %.5f (noisy %.5f)" % (state["step"], v, vn), flush=True)
    save()


if __name__ == "__main__":
    main()
