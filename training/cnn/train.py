#!/usr/bin/python3
"""Trains the KPCN (model.py) on the generated Cycles crops (training/datagen).

    nice -n 10 /usr/bin/python3 training/cnn/train.py --minutes 35            # fresh run
    nice -n 10 /usr/bin/python3 training/cnn/train.py --resume --minutes 60   # continue
    /usr/bin/python3 training/cnn/train.py --patches FILE.npz --device cuda   # a GPU machine

Data (--dataset): `n2n` (default, issue 47: $CACHE/datasets/n2n, levels 4/16/64, each crop's
target an independent 128-spp render) or `full` (the older crops with 1024-spp references,
levels 4/16/64/256). The n2n split holds out whole families: VALIDATION_FAMILIES are
validated on (whole crops at 16 and 64 spp), TEST_FAMILIES only measured (bench); the
`full` split validates on crops whose number % 6 == 4. Never ../shared/data. New crops are
picked up at every validation. --patches trains from patches.py's compact set instead (the
same crops, cut once, float16: ~60 MiB for a GPU machine).

Patches (§5.1): 64x64 (--patch), centres drawn from a PDF over the crop that favours noisy
and detailed regions: 0.2 + relative colour variance + normal-gradient magnitude (each
scaled to mean 1), so flat regions are still seen. Augmentation: the 8 flips/transposes
(normals rotated with the image), an exposure scale 2^U(-2, 2) of every radiance plane
(variances by its square), and samples shown without some inputs, as renders without them
reach the op (drop_inputs): --no-split without the diffuse/specular split (Tungsten's files,
a beauty alone), --no-variance without variances, --no-depth without depth. The one network
then also is the colour + albedo + normal model (issue 47's (b)).

Loss (--loss): `n2n` (the default with n2n data): relative squared error of the diffuse,
specular and recombined colour, divided by the output's own square + 0.01 with no gradient
through the divisor (Lehtinen et al. 2018, Noise2Noise §3.4): its expectation over the
target's noise is the loss against the clean image plus a constant, so a noisy independent
target trains as a clean one would. `l1log` (the default with `full`): L1 in log(1 + x),
KPCN §5.2, for clean references only (it is biased under target noise). `n2n_capped`: n2n
with each pixel's term at most 1, so that a target's firefly does not set the step (the best
of the three on the validation families: models/README-kpcn.md). Adam. --init starts from
exported weights (a fine-tune).

Run state in $CACHE/cnn/<--run>/ (default `run`): checkpoint.pt (model, optimizer, step,
elapsed, curve, arguments; written every 50 steps and at the end, atomically), loss.csv
(step, minutes, train loss, validation relMSE), model_last.npz and model_best.npz (the
weights alone, as numpy: last, and at the best validation), state.json (the run's state
without the optimizer: what export.py reads). SIGTERM/SIGINT save and stop.
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
# The n2n set's crops hold renders at 4, 16 and 64 spp and a 128-spp target, all of
# independent seeds. SWAPPED is one more level at no render cost: the target as the input
# (128 spp, its variance and features) and the three renders' sample-weighted mean as its
# target (84 spp, independent of it): a network that reads no variance (model b) sees no
# render cleaner than 64 spp without it, and smooths 256-spp renders as if they were 64.
SWAPPED = 128
LEVELS = {"n2n": (4, 16, 64, SWAPPED), "full": (4, 16, 64, 256)}
VAL_LEVELS = (16, 64, SWAPPED)
RADIANCE = ("color", "diffuse", "specular")
VARIANCES = ("color_var", "diffuse_var", "specular_var")
# Held out of training, whole families (issue 47): validation picks the run's settings,
# test is measured only (bench/report).
VALIDATION_FAMILIES = ("bump", "anisotropic")
TEST_FAMILIES = ("dof", "many_lights", "water")
HELD_OUT = VALIDATION_FAMILIES + TEST_FAMILIES


def family_of(crop_dir):
    """'0012_many_lights' -> 'many_lights'."""
    return os.path.basename(crop_dir).split("_", 1)[1]


def split_of(dataset, crop_dir):
    if dataset == "full":
        m = re.match(r"(\d+)_", os.path.basename(crop_dir))
        return "val" if m is not None and int(m.group(1)) % 6 == 4 else "train"
    family = family_of(crop_dir)
    return "val" if family in VALIDATION_FAMILIES else "test" if family in TEST_FAMILIES else "train"


def list_files(dataset="n2n"):
    """(training, validation) lists of (prefix, spp); the test families are in neither."""
    train, val = [], []
    for crop in data.crops(os.path.join(CACHE, "datasets", dataset)):
        name = os.path.basename(crop)
        split = split_of(dataset, crop)
        for spp in LEVELS[dataset]:
            prefix = os.path.join(crop, name)
            needed = ["%s_%04dspp_var.exr" % (prefix, level) for level in LEVELS[dataset]
                      if level != SWAPPED] if spp == SWAPPED else ["%s_%04dspp_var.exr" % (prefix, spp)]
            if not all(os.path.exists(path) for path in needed):
                continue
            if split == "train":
                train.append((prefix, spp))
            elif split == "val" and spp in VAL_LEVELS:
                val.append((prefix, spp))
    return train, val


_cache = {}


def load(prefix, spp):
    """Raw planes as torch tensors [C, H, W] (depth scaled), the target (colour, diffuse,
    specular), the target colour's variance of the mean, and the patch PDF."""
    key = (prefix, spp)
    if key in _cache:
        return _cache[key]
    if spp == SWAPPED:
        # The target as the input; the renders' sample-weighted mean, and its variance of the
        # mean, as the target.
        raw = data.load_render(prefix + "_ref.exr")
        levels = [level for level in LEVELS["n2n"] if level != SWAPPED]
        total = float(sum(levels))
        ref = [sum(level / total * r for level, r in
                   zip(levels, parts)) for parts in
               zip(*[data.load_reference("%s_%04dspp.exr" % (prefix, level)) for level in levels])]
        ref_var = sum((level / total) ** 2 * data.load_reference_variance("%s_%04dspp_var.exr" % (prefix, level))
                      for level in levels)
    else:
        raw = data.load_render(prefix, spp)
        ref = data.load_reference(prefix + "_ref.exr")
        ref_var = data.load_reference_variance(prefix + "_ref_var.exr")
    raw = {k: torch.from_numpy(v) for k, v in raw.items()}
    raw["depth"], raw["depth_var"] = kpcn.scale_depth(raw["depth"], raw["depth_var"])
    ref = [torch.from_numpy(np.ascontiguousarray(r, dtype=np.float32)) for r in ref]
    ref_var = torch.from_numpy(np.ascontiguousarray(ref_var, dtype=np.float32))
    # §5.1 patch PDF: noisy (relative colour variance) and detailed (normal gradients) regions.
    rel_var = (raw["color_var"] / (raw["color"] ** 2 + 1e-2)).mean(0)
    gx = torch.zeros_like(raw["normal"])
    gy = torch.zeros_like(raw["normal"])
    gx[:, :, :-1] = raw["normal"][:, :, 1:] - raw["normal"][:, :, :-1]
    gy[:, :-1, :] = raw["normal"][:, 1:, :] - raw["normal"][:, :-1, :]
    detail = (gx.abs() + gy.abs()).sum(0)
    pdf = 0.2 + rel_var / (rel_var.mean() + 1e-8) + detail / (detail.mean() + 1e-8)
    _cache[key] = (raw, ref, ref_var, torch.nan_to_num(pdf))
    return _cache[key]


def transform(t, k, flip, is_normal=False):
    """Rotation by k*90 degrees and an optional flip of [..., C, H, W]; normals (camera
    space, x right, y up) rotated with the image."""
    if flip:
        t = torch.flip(t, [-1])
        if is_normal:
            t = t * torch.tensor([-1.0, 1.0, 1.0], device=t.device).view(3, 1, 1)
    for _ in range(k):
        t = torch.rot90(t, 1, [-2, -1])  # counter-clockwise on screen
        if is_normal:
            t = torch.stack([-t[..., 1, :, :], t[..., 0, :, :], t[..., 2, :, :]], -3)  # (x, y) -> (-y, x)
    return t


def augment(raws, refs, exposure):
    """One flip/rotation for the batch, an exposure per sample ([N, 1, 1, 1])."""
    k, flip = random.randrange(4), random.random() < 0.5
    raws = {n: transform(t, k, flip, n == "normal") for n, t in raws.items()}
    refs = [transform(r, k, flip) for r in refs]
    for n in RADIANCE:
        raws[n] = raws[n] * exposure
    for n in VARIANCES:
        raws[n] = raws[n] * exposure ** 2
    return raws, [r * exposure for r in refs]


def drop_inputs(raws, refs, no_split, no_variance, no_depth):
    """Shows some samples as renders without some of the inputs show them to the op: without
    the diffuse/specular split (`no_split` of them: cnn_steps.h, diffuse zero and the colour
    the specular branch's input), without variances (`no_variance`: no variance file, every
    variance zero) and without depth (`no_depth`: read as zeros), each drawn independently.
    One network then serves every input a renderer writes, colour + albedo + normal too."""
    n = raws["color"].shape[0]
    device = raws["color"].device
    draw = lambda p: (torch.rand(n, device=device) < p).view(n, 1, 1, 1).float()  # noqa: E731
    split_off, var_off, depth_off = draw(no_split), draw(no_variance), draw(no_depth)
    raws = dict(raws)
    raws["diffuse"] = raws["diffuse"] * (1 - split_off)
    raws["diffuse_var"] = raws["diffuse_var"] * (1 - split_off)
    raws["specular"] = raws["color"] - raws["diffuse"]
    raws["specular_var"] = raws["specular_var"] * (1 - split_off) + raws["color_var"] * split_off
    for name in ("color_var", "diffuse_var", "specular_var", "albedo_var", "normal_var", "depth_var"):
        raws[name] = raws[name] * (1 - var_off)
    raws["depth"] = raws["depth"] * (1 - depth_off)
    raws["depth_var"] = raws["depth_var"] * (1 - depth_off)
    colour, diffuse, _ = refs
    diffuse = diffuse * (1 - split_off)
    return raws, [colour, diffuse, colour - diffuse]


def sample_batch(files, batch, patch, device):
    """A batch of patches cut from the EXR crops."""
    raws, refs = {}, []
    for _ in range(batch):
        prefix, spp = random.choice(files)
        raw, ref, _, pdf = load(prefix, spp)
        h, w = pdf.shape
        size = min(patch, h, w) // 4 * 4
        # centre drawn from the PDF, then clamped so the patch fits
        idx = int(torch.multinomial(pdf.flatten(), 1))
        cy, cx = idx // w, idx % w
        y0 = min(max(cy - size // 2, 0), h - size)
        x0 = min(max(cx - size // 2, 0), w - size)
        patch = size  # small crops: every patch at the smallest size
        for name, t in raw.items():
            raws.setdefault(name, []).append(t[:, y0:y0 + size, x0:x0 + size])
        refs.append([r[:, y0:y0 + size, x0:x0 + size] for r in ref])
    raws = {n: torch.stack([t[..., :patch, :patch] for t in v]).to(device) for n, v in raws.items()}
    ref = [torch.stack([r[i][..., :patch, :patch] for r in refs]).to(device) for i in range(3)]
    return raws, ref


class PatchSet:
    """patches.py's compact set, on the training device."""

    def __init__(self, path, device):
        import patches as ps
        with np.load(path) as f:
            self.patches = torch.from_numpy(f["patches"]).to(device)
        self.slices = {}
        c = 0
        for name, n in ps.PLANES:
            self.slices[name] = slice(c, c + n)
            c += n
        self.device = device

    def __len__(self):
        return self.patches.shape[0]

    def sample(self, batch, patch):
        idx = torch.randint(0, len(self), (batch,), device=self.device)
        p = self.patches[idx].float()
        size = min(patch, p.shape[-1]) // 4 * 4
        y0, x0 = (random.randint(0, p.shape[-1] - size) for _ in range(2))
        return self.planes(p[..., y0:y0 + size, x0:x0 + size])

    def planes(self, p):
        """A batch of stored patches [N, C, P, P] as (raw planes, [colour, diffuse, specular]
        of the target)."""
        raws = {name: p[:, s] for name, s in self.slices.items() if not name.startswith("target_")}
        raws["specular"] = raws["color"] - raws["diffuse"]
        colour, diffuse = p[:, self.slices["target_color"]], p[:, self.slices["target_diffuse"]]
        return raws, [colour, diffuse, colour - diffuse]


def loss_l1log(out, ref):
    diffuse, specular, colour = out
    ref_colour, ref_diffuse, ref_specular = ref
    l1 = lambda a, b: (torch.log1p(torch.relu(a)) - torch.log1p(torch.relu(b))).abs().mean()  # noqa: E731
    return l1(diffuse, ref_diffuse) + l1(specular, ref_specular) + l1(colour, ref_colour)


def loss_n2n(out, ref):
    diffuse, specular, colour = out
    ref_colour, ref_diffuse, ref_specular = ref
    rel = lambda a, b: ((a - b) ** 2 / (a.detach() ** 2 + 0.01)).mean()  # noqa: E731
    return rel(diffuse, ref_diffuse) + rel(specular, ref_specular) + rel(colour, ref_colour)


def loss_n2n_capped(out, ref):
    """loss_n2n with each pixel's term at most 1: a target's firefly no longer outweighs the
    batch (biased where it caps, which a converged pixel of a 128-spp target rarely needs)."""
    diffuse, specular, colour = out
    ref_colour, ref_diffuse, ref_specular = ref
    rel = lambda a, b: ((a - b) ** 2 / (a.detach() ** 2 + 0.01)).clamp(max=1.0).mean()  # noqa: E731
    return rel(diffuse, ref_diffuse) + rel(specular, ref_specular) + rel(colour, ref_colour)


LOSSES = {"n2n": loss_n2n, "n2n_capped": loss_n2n_capped, "l1log": loss_l1log}


def relmse(image, reference, reference_var=None):
    """relMSE (0.01 offset); with the reference's variance of the mean, that variance is taken
    off the squared error: an unbiased estimate of the error against the clean image."""
    err = (image - reference) ** 2
    if reference_var is not None:
        err = err - reference_var
    return float((err / (reference ** 2 + 0.01)).mean())


def validate(net, files, device, without=(0.0, 0.0, 0.0)):
    """Mean relMSE of the denoised colour and of the noisy input over whole validation crops,
    shown without the inputs that `without` (drop_inputs' no_split, no_variance, no_depth,
    each 0 or 1) takes away: a run that always trains without them is measured so."""
    if not files:
        return float("nan"), float("nan")
    net.eval()
    errors, noisy = [], []
    with torch.no_grad():
        for prefix, spp in files:
            raw, ref, ref_var, _ = load(prefix, spp)
            h, w = raw["color"].shape[1:]
            a = kpcn.alignment(net.diffuse.widths)
            h4, w4 = h // a * a, w // a * a
            batch = {k: v[None, :, :h4, :w4].to(device) for k, v in raw.items()}
            if any(without):
                refs = [r[None, :, :h4, :w4].to(device) for r in ref]
                batch, _ = drop_inputs(batch, refs, *without)
            _, _, colour = net(batch)
            target, target_var = ref[0][:, :h4, :w4], ref_var[:, :h4, :w4]
            errors.append(relmse(colour[0].cpu(), target, target_var))
            noisy.append(relmse(raw["color"][:, :h4, :w4], target, target_var))
    net.train()
    return float(np.mean(errors)), float(np.mean(noisy))


def validate_patches(net, patch_set, device, batch=16):
    """Mean relMSE (against the noisy target: comparable between runs, not an error against
    the clean image) of the denoised colour and of the input over a validation patch set."""
    net.eval()
    errors, noisy = [], []
    with torch.no_grad():
        for i in range(0, len(patch_set), batch):
            raws, (target, _, _) = patch_set.planes(patch_set.patches[i:i + batch].float())
            _, _, colour = net(raws)
            errors.append(((colour - target) ** 2 / (target ** 2 + 0.01)).mean((1, 2, 3)))
            noisy.append(((raws["color"] - target) ** 2 / (target ** 2 + 0.01)).mean((1, 2, 3)))
    net.train()
    return float(torch.cat(errors).mean()), float(torch.cat(noisy).mean())


def load_weights(path):
    """A state dict from an exported model (.mcdnw, training/common/weights.py) or a run's
    model_*.npz."""
    if path.endswith(".mcdnw"):
        sys.path.insert(0, os.path.join(HERE, "..", "common"))
        from weights import read_weights
        _, tensors = read_weights(path)
    else:
        with np.load(path) as f:
            tensors = {k: f[k] for k in f.files}
    return {k: torch.from_numpy(np.ascontiguousarray(v)) for k, v in tensors.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--resume", action="store_true", help="continue from $CACHE/cnn/<run>/checkpoint.pt")
    ap.add_argument("--run", default="run", help="run directory under $CACHE/cnn (default run)")
    ap.add_argument("--dataset", choices=sorted(LEVELS), default="n2n")
    ap.add_argument("--patches", help="train from patches.py's compact set (validation: none "
                    "unless the dataset is here too)")
    ap.add_argument("--val-patches", help="validate on this patch set (patches.py --split val) "
                    "instead of the validation crops")
    ap.add_argument("--loss", choices=sorted(LOSSES), help="default: n2n, l1log for --dataset full")
    ap.add_argument("--init", help="start from these weights (an exported .mcdnw or a run's "
                    ".npz) instead of random ones: a fine-tune (their widths are used; a --widths "
                    "with more or wider levels grows the network first: model.grow)")
    ap.add_argument("--widths", default=",".join(str(w) for w in kpcn.WIDTHS),
                    help="UNet widths at full, 1/2, 1/4, ... resolution, one per level "
                    "(default %(default)s)")
    ap.add_argument("--no-split", type=float, default=0.25,
                    help="fraction of samples shown without the diffuse/specular split")
    ap.add_argument("--no-variance", type=float, default=0.25,
                    help="fraction of samples shown without variances")
    ap.add_argument("--no-depth", type=float, default=0.25,
                    help="fraction of samples shown without depth")
    ap.add_argument("--minutes", type=float, default=35, help="wall-clock budget of this session")
    ap.add_argument("--steps", type=int, default=0, help="stop at this total step (0: no limit)")
    ap.add_argument("--batch", type=int, default=8)
    ap.add_argument("--patch", type=int, default=64)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--lr-final", type=float, default=0,
                    help="cosine decay from --lr to this over --steps, or without --steps over "
                         "this session's --minutes (0: constant --lr)")
    ap.add_argument("--validate-every", type=int, default=200)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--device", default="auto", help="cpu, cuda or auto (cuda when present)")
    ap.add_argument("--seed", type=int, default=1)
    args = ap.parse_args()
    device = torch.device("cuda" if args.device == "auto" and torch.cuda.is_available()
                          else "cpu" if args.device == "auto" else args.device)
    torch.set_num_threads(args.threads)
    loss_fn = LOSSES[args.loss or ("l1log" if args.dataset == "full" else "n2n")]
    widths = tuple(int(w) for w in args.widths.split(","))
    run = os.path.join(CACHE, "cnn", args.run)
    os.makedirs(run, exist_ok=True)
    checkpoint_path = os.path.join(run, "checkpoint.pt")

    state = {"step": 0, "elapsed": 0.0, "curve": [], "args": vars(args)}
    ck = None
    if args.resume and os.path.exists(checkpoint_path):
        ck = torch.load(checkpoint_path, map_location="cpu")
        state = ck["state"]
        widths = tuple(state["args"].get("widths_used", kpcn.WIDTHS))
    elif os.path.exists(checkpoint_path) and not args.resume:
        sys.exit("%s exists: pass --resume to continue it, or remove it to start over" % checkpoint_path)
    init = None
    if args.init and ck is None:
        init = load_weights(args.init)
        init_widths = kpcn.widths_of(init)
        if widths != init_widths and len(widths) >= len(init_widths) and all(
                w >= o for w, o in zip(widths, init_widths)):
            init = kpcn.grow(init, widths)
            print("grew %s to %s (the same function to start)" % (init_widths, widths), flush=True)
        widths = kpcn.widths_of(init)
    state["args"]["widths_used"] = list(widths)
    net = kpcn.KPCN(widths).to(device)
    if init is not None:
        net.load_state_dict({k: v.to(device) for k, v in init.items()})
        print("initialised from %s" % args.init, flush=True)
    opt = torch.optim.Adam(net.parameters(), lr=args.lr)
    if ck is not None:
        net.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        print("resumed at step %d (%.1f min trained)" % (state["step"], state["elapsed"] / 60), flush=True)
    random.seed(args.seed + state["step"])
    torch.manual_seed(args.seed + state["step"])
    print("widths %s: %.0f kFLOP per pixel (both branches), device %s, loss %s" % (
        widths, 2 * kpcn.flops_per_pixel(widths) / 1e3, device, loss_fn.__name__), flush=True)

    stop = {"now": False}
    signal.signal(signal.SIGTERM, lambda *a: stop.update(now=True))
    signal.signal(signal.SIGINT, lambda *a: stop.update(now=True))

    def save_weights(name):
        """The model's weights alone as numpy (any PyTorch version reads them: a GPU
        machine's run comes back as these)."""
        tmp = os.path.join(run, name + ".tmp.npz")
        np.savez(tmp, **{k: v.detach().cpu().numpy() for k, v in net.state_dict().items()})
        os.replace(tmp, os.path.join(run, name + ".npz"))

    def note_validation(v):
        """Keeps the weights of the best validation so far (model_best.npz)."""
        if math.isfinite(v) and v < state.get("best_val", float("inf")):
            state["best_val"], state["best_step"] = v, state["step"]
            save_weights("model_best")

    def save():
        save_weights("model_last")
        with open(os.path.join(run, "state.json.tmp"), "w") as f:
            json.dump(state, f, indent=1)
        os.replace(os.path.join(run, "state.json.tmp"), os.path.join(run, "state.json"))
        tmp = checkpoint_path + ".tmp"
        torch.save({"model": net.state_dict(), "optimizer": opt.state_dict(), "state": state}, tmp)
        os.replace(tmp, checkpoint_path)
        with open(os.path.join(run, "loss.csv"), "w", newline="") as f:
            wr = csv.writer(f)
            wr.writerow(["step", "minutes", "train_loss", "val_relmse", "val_noisy_relmse", "train_files"])
            for row in state["curve"]:
                wr.writerow(row)

    patch_set = PatchSet(args.patches, device) if args.patches else None
    val_set = PatchSet(args.val_patches, device) if args.val_patches else None

    # A run that always trains without an input (model b: colour + albedo + normal) is
    # validated without it.
    without = tuple(float(p >= 1) for p in (args.no_split, args.no_variance, args.no_depth))

    def run_validation():
        if val_set:
            return validate_patches(net, val_set, device)
        return validate(net, val_files, device, without)

    train_files, val_files = list_files(args.dataset)
    n_train = len(patch_set) if patch_set else len(train_files)
    print("train %s %d, validation files %d" % ("patches" if patch_set else "files", n_train,
                                                len(val_files)), flush=True)
    start = time.time()
    elapsed0 = state["elapsed"]
    running = []
    if init is not None and state["step"] == 0:
        # Where a fine-tune starts: the first point of its curve is the initial weights'.
        v, vn = run_validation()
        note_validation(v)
        state["curve"].append([0, 0.0, float("nan"), v, vn,
                               len(patch_set) if patch_set else len(train_files)])
        print("  validation at the start relMSE %.5f (noisy %.5f)" % (v, vn), flush=True)
    while not stop["now"]:
        if args.steps and state["step"] >= args.steps:
            break
        if time.time() - start > args.minutes * 60:
            break
        if args.lr_final:
            t = min(1.0, state["step"] / args.steps if args.steps else
                    (time.time() - start) / (args.minutes * 60))
            for g in opt.param_groups:
                g["lr"] = args.lr_final + 0.5 * (args.lr - args.lr_final) * (1 + math.cos(math.pi * t))
        else:
            for g in opt.param_groups:
                g["lr"] = args.lr
        if patch_set:
            raws, ref = patch_set.sample(args.batch, args.patch)
        else:
            raws, ref = sample_batch(train_files, args.batch, args.patch, device)
        exposure = 2.0 ** (torch.rand(args.batch, 1, 1, 1, device=device) * 4 - 2)
        raws, ref = augment(raws, ref, exposure)
        raws, ref = drop_inputs(raws, ref, args.no_split, args.no_variance, args.no_depth)
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
                train_files, val_files = list_files(args.dataset)
                v, vn = run_validation()
                note_validation(v)
                state["curve"].append([state["step"], round(state["elapsed"] / 60, 2),
                                       round(float(np.mean(running[-50:])), 5), v, vn,
                                       len(patch_set) if patch_set else len(train_files)])
                print("  validation relMSE %.5f (noisy %.5f), %d train files" % (v, vn, len(train_files)), flush=True)
            save()
    v, vn = run_validation()
    note_validation(v)
    state["curve"].append([state["step"], round(state["elapsed"] / 60, 2),
                           round(float(np.mean(running[-50:] or [float("nan")])), 5), v, vn,
                           len(patch_set) if patch_set else len(train_files)])
    print("final step %d: validation relMSE %.5f (noisy %.5f)" % (state["step"], v, vn), flush=True)
    save()


if __name__ == "__main__":
    main()
