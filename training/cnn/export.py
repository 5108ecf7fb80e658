#!/usr/bin/python3
"""Exports the trained KPCN and remakes the C++ test fixture.

    /usr/bin/python3 training/cnn/export.py            # checkpoint -> models/kpcn.mcdnw
    /usr/bin/python3 training/cnn/export.py --fixture  # only tests/data/cnn/*

Writes
  models/kpcn.mcdnw        the two branches ("diffuse.*", "specular.*"), metadata with the
                           input layout, widths, training steps/time/data and final metrics
  models/kpcn_loss.csv     the training curve ($CACHE/cnn/run/loss.csv)
  tests/data/cnn/kpcn_tiny.mcdnw, kpcn_tiny_io.mcdnw
                           a small random network of the same architecture (peaky kernels)
                           and model.denoise's output on tests/data/generated/0000_interior
                           at 16 spp, whole (32x32) and cut to 29x30 (the padding path):
                           tests/cnn/pytorch_test.cpp runs the C++ op on the same files.
"""
import argparse
import os
import shutil
import sys

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(ROOT, "training", "common"))
import data  # noqa: E402
import model as kpcn  # noqa: E402
from weights import write_weights  # noqa: E402

CACHE = os.environ.get("MCDN_CACHE", os.path.expanduser("~/.cache/mcdenoise"))
RUN = os.path.join(CACHE, "cnn", "run")
FIXTURE_RENDER = os.path.join(ROOT, "tests", "data", "generated", "0000_interior", "0000_interior")
CUT = (30, 29)  # rows, columns of the cut fixture (not multiples of 4)


def metadata(net, extra=None):
    meta = {"network": "kpcn", "input_layout": kpcn.INPUT_LAYOUT,
            "widths": list(net.diffuse.widths),
            "kernel": kpcn.KERNEL, "iterations": net.diffuse.iterations,
            "albedo_epsilon": kpcn.ALBEDO_EPSILON,
            "gflop_1080p_both_branches": round(
                kpcn.flops_per_pixel(net.diffuse.widths) * 1920 * 1080 * 2 / 1e9, 1)}
    meta.update(extra or {})
    return meta


def make_fixture():
    torch.manual_seed(6)
    net = kpcn.KPCN(widths=(8, 8, 8, 8))  # 4 levels: the C++ reads any depth
    with torch.no_grad():
        for branch in (net.diffuse, net.specular):
            branch.kernels.weight.normal_(std=0.5)  # peaky, varied kernels: a demanding test
            branch.kernels.bias.normal_(std=0.5)
            for m in branch.modules():
                if isinstance(m, torch.nn.Conv2d) and m is not branch.kernels:
                    m.bias.normal_(std=0.05)
    os.makedirs(os.path.join(ROOT, "tests", "data", "cnn"), exist_ok=True)
    meta = metadata(net, {"purpose": "test fixture (random weights)"})
    meta["widths"] = [8, 8, 8, 8]
    meta.pop("gflop_1080p_both_branches")
    write_weights(os.path.join(ROOT, "tests", "data", "cnn", "kpcn_tiny.mcdnw"), net.state_dict(), meta)
    raw = {k: torch.from_numpy(v) for k, v in data.load_render(FIXTURE_RENDER, 16).items()}
    whole = kpcn.denoise(net, raw)
    cut = kpcn.denoise(net, {k: v[:, :CUT[0], :CUT[1]] for k, v in raw.items()})
    hwc = lambda t: t.permute(1, 2, 0).contiguous()  # noqa: E731
    write_weights(os.path.join(ROOT, "tests", "data", "cnn", "kpcn_tiny_io.mcdnw"),
                  {"output.color": hwc(whole), "output.color_cut": hwc(cut)},
                  {"render": "tests/data/generated/0000_interior/0000_interior_0016spp.exr",
                   "cut": list(CUT)})
    print("fixture: colour range %.4g..%.4g" % (float(whole.min()), float(whole.max())))


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--fixture", action="store_true", help="only remake the test fixture")
    ap.add_argument("--out", default=os.path.join(ROOT, "models", "kpcn.mcdnw"))
    ap.add_argument("--run", default="run", help="the run under $CACHE/cnn (train.py --run)")
    ap.add_argument("--which", choices=("best", "last"), default="best",
                    help="the weights at the best validation (default) or the last")
    ap.add_argument("--data", default="training/datagen n2n set ($CACHE/datasets/n2n): 24 families, "
                    "128x128 crops at 4/16/64 spp, independent 128-spp targets (Noise2Noise); "
                    "validation families bump, anisotropic; test families dof, many_lights, water",
                    help="what the metadata says the model was trained on")
    args = ap.parse_args()
    make_fixture()
    if args.fixture:
        return
    run = os.path.join(CACHE, "cnn", args.run)
    import json
    with open(os.path.join(run, "state.json")) as f:
        state = json.load(f)
    with np.load(os.path.join(run, "model_%s.npz" % args.which)) as f:
        state_dict = {k: torch.from_numpy(f[k]) for k in f.files}
    widths = kpcn.widths_of(state_dict)
    net = kpcn.KPCN(widths)
    net.load_state_dict(state_dict)
    curve = state["curve"]
    meta = metadata(net, {
        "training": {"steps": state["step"], "minutes": round(state["elapsed"] / 60, 1),
                     "weights_at_step": state.get("best_step") if args.which == "best" else state["step"],
                     "batch": state["args"]["batch"], "patch": state["args"]["patch"],
                     "loss": state["args"].get("loss") or "n2n", "data": args.data,
                     "last_validation": curve[-1] if curve else None}})
    # What the run always trained without (train.py's drop_inputs at 1): a model trained with
    # its depth always zero is given zero depth by the op (cnn_steps.h Model::reads_depth).
    without = [name for name in ("split", "variance", "depth")
               if state["args"].get("no_" + name, 0) >= 1]
    if without:
        meta["training"]["always_without"] = without
    if "depth" in without:
        meta["reads_depth"] = False
    write_weights(args.out, net.state_dict(), meta)
    # The curve beside the weights: kpcn.mcdnw's as kpcn_loss.csv.
    curve_path = os.path.splitext(args.out)[0] + "_loss.csv"
    shutil.copyfile(os.path.join(run, "loss.csv"), curve_path)
    print("wrote %s (widths %s, step %s of %d, %.1f min)" % (
        args.out, widths, meta["training"]["weights_at_step"], state["step"], state["elapsed"] / 60))


if __name__ == "__main__":
    main()
