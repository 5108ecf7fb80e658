#!/usr/bin/python3
"""Trains the mixing network of progressive denoising (PD §4.3, §5.3) on prepare.py's data.

    /usr/bin/python3 training/mix/train.py [--steps 3000] [--max-lr 5e-4] [--run-dir DIR]
    /usr/bin/python3 training/mix/train.py --extend 2000     # another one-cycle, same weights

Resumable: every --checkpoint-every steps (and at the end) DIR/checkpoint.pt holds the
weights, Adam's state, the schedule and the random generators; rerunning the same command
continues where it stopped (data prepared since then joins the training set).
DIR (default $CACHE/mix/run) also gets loss.csv and loss.png (the loss curve).

Per step: a batch of 12 random 64x64 patches (whole crop if smaller) of random files, each
with a random flip/rotation (8 symmetries of the square), a random exposure (--exposure E:
every radiance plane times s = 2^u, u uniform in [-E, E], and every squared-error plane times
s^2, so the sample stays consistent; the HDR/DEN inputs are log-scaled, not scale-free, and a
scene brighter than the training crops, e.g. a visible emitter's edge, was read wrongly)
and, with probability 1/2, HDR<->DEN and VAR<->SURE swapped (§4.3; the network then predicts beta = 1 - alpha of
z = y + beta (x - y)). Loss: SMAPE of z against the reference, plus --log-l1-weight times
the L1 distance of their signed log1p (model.log_l1: SMAPE alone lets render fireflies
through, its gradient vanishes on them). Adam, one-cycle schedule.
An "epoch" is as many patches as there are training files.

Validation: whole crops of the held-out generated crops (crop number % 6 == 4 in
datasets/full and datasets/mix-hq), no swap, as at inference (without the t-test, which is applied after the
network, PD §4.2).
"""
import argparse
import csv
import glob
import math
import os
import sys
import time

import numpy as np
import torch

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from model import PLANES, MixNet, load_sample, log_l1, mix, relmse, smape  # noqa: E402

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from weights import read_weights  # noqa: E402

CACHE = os.environ.get("MCDN_CACHE", os.path.expanduser("~/.cache/mcdenoise"))
PREPARED = os.path.join(CACHE, "mix", "prepared")
INPUT_PLANES = PLANES[:-1]


def is_validation(path):
    """Held-out crops: datasets/full and datasets/mix-hq crops whose number % 6 == 4 (0004,
    0010, ...), with any denoiser's outputs (prepared/full, prepared/full.cnn, ...)."""
    name = os.path.basename(path)
    dataset = os.path.basename(os.path.dirname(path)).split(".")[0]
    return dataset in ("full", "mix-hq") and int(name[:4]) % 6 == 4


def scan(datasets):
    files = sorted(f for d in datasets for f in glob.glob(os.path.join(PREPARED, d, "*.npz")))
    return [f for f in files if not is_validation(f)], [f for f in files if is_validation(f)]


def to_tensors(sample):
    return {k: torch.from_numpy(sample[k]) for k in PLANES}


# Planes in units of radiance and of squared radiance (scaled by s and s^2 for exposure).
RADIANCE_PLANES = ("x", "y", "reference")
SQUARED_PLANES = ("variance", "sure", "divergence", "residual")


def random_batch(samples, batch, patch, rng, exposure=0.0):
    """Stacked planes {name: [batch, 3, p, p]} and the swap mask [batch]."""
    assert set(RADIANCE_PLANES + SQUARED_PLANES) == set(PLANES)
    out = {k: [] for k in PLANES}
    for _ in range(batch):
        s = samples[rng.integers(len(samples))]
        h, w = s["x"].shape[1:]
        p = min(patch, h, w)
        y0, x0 = rng.integers(h - p + 1), rng.integers(w - p + 1)
        k, flip = int(rng.integers(4)), bool(rng.integers(2))
        scale = 2.0 ** rng.uniform(-exposure, exposure) if exposure > 0 else 1.0
        for name in PLANES:
            t = s[name][:, y0:y0 + p, x0:x0 + p]
            if scale != 1.0:
                t = t * (scale if name in RADIANCE_PLANES else scale * scale)
            t = torch.rot90(t, k, dims=(1, 2))
            if flip:
                t = torch.flip(t, dims=(2,))
            out[name].append(t)
    # Crops smaller than the patch (datasets/small, 64x64) only when patch <= 64.
    stacked = {k: torch.stack(v) for k, v in out.items()}
    swap = torch.from_numpy(rng.integers(2, size=batch).astype(bool))
    return stacked, swap


@torch.no_grad()
def validate(net, samples):
    """Mean over the validation files of SMAPE and of relMSE of the mix, the render and the
    denoised image (in that order)."""
    net.eval()
    totals = np.zeros(6)
    for s in samples:
        b = {k: v.unsqueeze(0) for k, v in s.items()}
        z, _ = mix(net, *(b[k] for k in INPUT_PLANES))
        r = b["reference"]
        totals += [metric(image, r).item() for metric in (smape, relmse)
                   for image in (z, b["x"], b["y"])]
    net.train()
    return totals / max(len(samples), 1)


# loss.csv's columns; the last four came with the log-L1 term (a run's older rows lack them).
CSV_COLUMNS = ["step", "epoch", "lr", "train_smape", "val_smape", "val_render_smape",
               "val_denoised_smape", "seconds", "train_files", "train_log_l1", "val_relmse",
               "val_render_relmse", "val_denoised_relmse"]


def open_log(csv_path):
    """loss.csv for appending, with the header of CSV_COLUMNS (an older file's header is
    rewritten; its rows keep their values)."""
    if os.path.exists(csv_path):
        rows = list(csv.reader(open(csv_path)))
        if rows and rows[0] != CSV_COLUMNS:
            with open(csv_path + ".tmp", "w", newline="") as f:
                csv.writer(f).writerows([CSV_COLUMNS] + rows[1:])
            os.replace(csv_path + ".tmp", csv_path)
    new = not os.path.exists(csv_path)
    log = open(csv_path, "a", newline="")
    if new:
        csv.writer(log).writerow(CSV_COLUMNS)
    return log


def plot_png(csv_path, png_path, width=640, height=360):
    """The loss curve (train SMAPE grey, validation SMAPE red, validation of the denoised
    image alone blue dashed) as a PNG, drawn with numpy (no matplotlib on Debian's python)."""
    import OpenImageIO as oiio
    rows = list(csv.DictReader(open(csv_path)))
    if len(rows) < 2:
        return
    steps = np.array([float(r["step"]) for r in rows])
    series = [("train_smape", (0.6, 0.6, 0.6), 1), ("val_smape", (0.9, 0.1, 0.1), 1),
              ("val_denoised_smape", (0.1, 0.3, 0.9), 2)]
    values = {k: np.array([float(r[k]) if r[k] else np.nan for r in rows]) for k, _, _ in series}
    finite = np.concatenate([v[np.isfinite(v)] for v in values.values()])
    lo, hi = finite.min() * 0.95, np.percentile(finite, 99) * 1.05
    img = np.ones((height, width, 3), np.float32)
    m = 30
    img[m:height - m, m] = 0
    img[height - m, m:width - m] = 0
    for key, colour, dash in series:
        v = values[key]
        ok = np.isfinite(v)
        if ok.sum() < 2:
            continue
        xs = m + (steps[ok] - steps.min()) / max(steps.max() - steps.min(), 1) * (width - 2 * m)
        ys = height - m - (np.clip(v[ok], lo, hi) - lo) / (hi - lo) * (height - 2 * m)
        for i in range(len(xs) - 1):
            n = int(max(abs(xs[i + 1] - xs[i]), abs(ys[i + 1] - ys[i]), 1)) * 2
            for t in np.linspace(0, 1, n):
                if dash == 2 and int(t * n / 6) % 2:
                    continue
                px, py = int(xs[i] + t * (xs[i + 1] - xs[i])), int(ys[i] + t * (ys[i + 1] - ys[i]))
                img[max(py - 1, 0):py + 1, max(px - 1, 0):px + 1] = colour
    buf = oiio.ImageBuf(oiio.ImageSpec(width, height, 3, oiio.FLOAT))
    buf.set_pixels(oiio.ROI(0, width, 0, height, 0, 1, 0, 3), img)
    buf.write(png_path, oiio.UINT8)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--run-dir", default=os.path.join(CACHE, "mix", "run"))
    ap.add_argument("--datasets", default="full,small")
    ap.add_argument("--steps", type=int, default=None,
                    help="steps of the one-cycle schedule (default 3000); given when resuming, "
                         "the running cycle is stretched or shortened to this length")
    ap.add_argument("--extend", type=int, default=0,
                    help="after a finished run: another one-cycle of this many steps")
    ap.add_argument("--max-lr", type=float, default=5e-4)
    ap.add_argument("--log-l1-weight", type=float, default=1.0,
                    help="weight of the log-domain L1 term added to SMAPE (model.log_l1); "
                         "0 = SMAPE alone, as the paper")
    ap.add_argument("--leak", type=float, default=0.0,
                    help="surrogate gradient where f_act's clip is active (model.f_act); 0 = exact")
    ap.add_argument("--exposure", type=float, default=0.0,
                    help="random exposure of each patch, +-this many stops (0 = none)")
    ap.add_argument("--batch", type=int, default=12)
    ap.add_argument("--patch", type=int, default=64)
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--log-every", type=int, default=25)
    ap.add_argument("--checkpoint-every", type=int, default=100)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--restart", action="store_true", help="ignore an existing checkpoint")
    ap.add_argument("--init", default="",
                    help="a fresh run starts from this exported network (e.g. models/mix.mcdnw, "
                         "to fine-tune the NFOR network for another denoiser) instead of at random")
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    os.makedirs(args.run_dir, exist_ok=True)
    ckpt_path = os.path.join(args.run_dir, "checkpoint.pt")
    csv_path = os.path.join(args.run_dir, "loss.csv")

    train_files, val_files = scan(args.datasets.split(","))
    if not train_files:
        sys.exit("train: no prepared data under %s: run training/mix/prepare.py" % PREPARED)
    train = [to_tensors(load_sample(f)) for f in train_files]
    val = [to_tensors(load_sample(f)) for f in val_files]
    print("train: %d files, validation: %d files (%s)" % (
        len(train), len(val), ", ".join(sorted({os.path.basename(f)[:-12] for f in val_files}))),
        flush=True)

    torch.manual_seed(args.seed)
    net = MixNet()
    opt = torch.optim.Adam(net.parameters(), lr=args.max_lr / 25)
    state = {"step": 0, "cycle_start": 0, "cycle_steps": args.steps or 3000, "seconds": 0.0,
             "patches": 0}
    rng = np.random.default_rng(args.seed)
    sched_state = None
    if os.path.exists(ckpt_path) and not args.restart:
        ck = torch.load(ckpt_path)
        net.load_state_dict(ck["model"])
        opt.load_state_dict(ck["optimizer"])
        state, sched_state = ck["state"], ck["scheduler"]
        rng.bit_generator.state = ck["numpy_rng"]
        torch.set_rng_state(ck["torch_rng"])
        print("resumed at step %d (%.0f s trained)" % (state["step"], state["seconds"]), flush=True)
    else:
        if os.path.exists(csv_path):
            os.remove(csv_path)
        if args.init:
            _, tensors = read_weights(args.init)
            net.load_state_dict({k: torch.from_numpy(v) for k, v in tensors.items()})
            print("started from %s" % args.init, flush=True)
    if args.extend:
        if state["step"] < state["cycle_start"] + state["cycle_steps"]:
            sys.exit("train: --extend needs a finished cycle; rerun without it to finish")
        state["cycle_start"], state["cycle_steps"] = state["step"], args.extend
        sched_state = None
        for g in opt.param_groups:
            g["lr"] = args.max_lr / 25
    # The record of the cycles run, for export.py's metadata.
    cycles = state.setdefault("cycles", [])
    if not cycles or cycles[-1]["start"] != state["cycle_start"]:
        cycles.append({"start": state["cycle_start"], "steps": state["cycle_steps"],
                       "max_lr": args.max_lr, "patch": args.patch, "batch": args.batch,
                       "leak": args.leak, "log_l1_weight": args.log_l1_weight,
                       "exposure": args.exposure, "datasets": args.datasets})
    done_in_cycle = state["step"] - state["cycle_start"]
    if sched_state is not None and args.steps and args.steps != state["cycle_steps"] \
            and not args.extend:
        if args.steps <= done_in_cycle:
            sys.exit("train: --steps %d: %d steps of this cycle are done already" % (args.steps, done_in_cycle))
        print("cycle length %d -> %d steps" % (state["cycle_steps"], args.steps), flush=True)
        state["cycle_steps"] = args.steps
        sched = torch.optim.lr_scheduler.OneCycleLR(
            opt, max_lr=opt.param_groups[0]["max_lr"], total_steps=args.steps,
            last_epoch=done_in_cycle - 1)
    else:
        sched = torch.optim.lr_scheduler.OneCycleLR(opt, max_lr=args.max_lr,
                                                    total_steps=state["cycle_steps"])
        if sched_state is not None:
            sched.load_state_dict(sched_state)

    def save():
        tmp = ckpt_path + ".tmp"
        torch.save({"model": net.state_dict(), "optimizer": opt.state_dict(),
                    "scheduler": sched.state_dict(), "state": state,
                    "numpy_rng": rng.bit_generator.state, "torch_rng": torch.get_rng_state(),
                    "args": vars(args), "train_files": [os.path.relpath(f, PREPARED) for f in train_files],
                    "val_files": [os.path.relpath(f, PREPARED) for f in val_files]}, tmp)
        os.replace(tmp, ckpt_path)

    log = open_log(csv_path)
    writer = csv.writer(log)
    end = state["cycle_start"] + state["cycle_steps"]
    running, running_log, count, t0 = 0.0, 0.0, 0, time.time()
    train_files, val_files = list(train_files), list(val_files)
    while state["step"] < end:
        batch, swap = random_batch(train, args.batch, args.patch, rng, args.exposure)
        z, _ = mix(net, *(batch[k] for k in INPUT_PLANES), swap=swap, leak=args.leak)
        smape_term = smape(z, batch["reference"])
        log_term = log_l1(z, batch["reference"])
        loss = smape_term + args.log_l1_weight * log_term
        opt.zero_grad()
        loss.backward()
        opt.step()
        sched.step()
        state["step"] += 1
        state["patches"] += args.batch
        state["epochs"] = state.get("epochs", state["patches"] / len(train)) + args.batch / len(train)
        running += smape_term.item()
        running_log += log_term.item()
        count += 1
        last = state["step"] == end
        if state["step"] % args.log_every == 0 or last:
            now = time.time()
            state["seconds"] += now - t0
            t0 = now
            row_val = [""] * 6
            if state["step"] % args.checkpoint_every == 0 or last:
                row_val = ["%.6g" % v for v in validate(net, val)] if val else row_val
            epoch = state["epochs"]
            writer.writerow([state["step"], "%.2f" % epoch, "%.3g" % opt.param_groups[0]["lr"],
                             "%.6f" % (running / count)] + row_val[:3]
                            + ["%.0f" % state["seconds"], len(train), "%.6f" % (running_log / count)]
                            + row_val[3:])
            log.flush()
            print("step %d  epoch %.1f  lr %.2g  train SMAPE %.5f log-L1 %.5f  val SMAPE %s "
                  "relMSE %s  %.0f s" % (
                      state["step"], epoch, opt.param_groups[0]["lr"], running / count,
                      running_log / count, "/".join(row_val[:3]), "/".join(row_val[3:]),
                      state["seconds"]), flush=True)
            running, running_log, count = 0.0, 0.0, 0
            if row_val[0]:
                save()
                # Crops the generator and prepare.py finished meanwhile join the training set.
                more_train, more_val = scan(args.datasets.split(","))
                for f in sorted(set(more_train) - set(train_files)):
                    train.append(to_tensors(load_sample(f)))
                    train_files.append(f)
                for f in sorted(set(more_val) - set(val_files)):
                    val.append(to_tensors(load_sample(f)))
                    val_files.append(f)
                plot_png(csv_path, os.path.join(args.run_dir, "loss.png"))
    print("done: step %d, %.0f s" % (state["step"], state["seconds"]))


if __name__ == "__main__":
    main()
