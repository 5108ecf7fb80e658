#!/usr/bin/python3
"""Exports the trained mixing network to the library's weights file, with its training record,
and remakes the PyTorch-vs-C++ fixture of tests/mix/net_test.cpp from the same weights.

    /usr/bin/python3 training/mix/export.py [--run-dir DIR] [--out models/mix.mcdnw]
    # the KPCN op's network (mcdn::mix picks it for frames the cnn op made):
    /usr/bin/python3 training/mix/export.py --run-dir DIR --denoiser cnn \
        --out models/mix_cnn.mcdnw --fixture ''
    # OIDN's (PD §6: the mix over the pre-trained OIDN):
    /usr/bin/python3 training/mix/export.py --run-dir DIR --denoiser oidn \
        --out models/mix_oidn.mcdnw --fixture ''

Writes
  models/mix.mcdnw            the weights (state_dict keys = the C++ parameter names) and
                              metadata: architecture, input layout and transforms, data,
                              steps/epochs, final train/validation SMAPE
  models/mix_loss.csv, .png   the loss curve of the run (copied from DIR; <out stem>_loss.*)
  tests/data/mix/mix_net_io.mcdnw   a 32x24 crop of a validation sample: the six input planes,
                              PyTorch's features, raw outputs and alpha (NHWC), and the
                              checksum of the weights they were computed with
"""
import argparse
import csv
import json
import os
import shutil
import sys

import numpy as np
import torch

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "common"))
import model as M  # noqa: E402
from weights import write_weights  # noqa: E402

ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
CACHE = os.environ.get("MCDN_CACHE", os.path.expanduser("~/.cache/mcdenoise"))


def nhwc(t):
    return t[0].permute(1, 2, 0).contiguous()


def weights_checksum(state):
    """Sum of |w| over every tensor, in double: the C++ test checks its fixture was made
    with the weights it loads."""
    return float(sum(np.abs(v.double().numpy()).sum() for v in state.values()))


def write_fixture(net, state, sample_path, out_path, y0=40, x0=30, h=24, w=32):
    s = M.load_sample(sample_path)
    planes = {k: torch.from_numpy(s[k][:, y0:y0 + h, x0:x0 + w].copy()).unsqueeze(0)
              for k in M.PLANES}
    with torch.no_grad():
        args = [planes[k] for k in M.PLANES[:-1]]
        feats = M.features(planes["x"], planes["y"], planes["variance"], planes["sure"],
                           planes["divergence"], planes["residual"], planes["y"])
        raw = net(feats)
        _, alpha = M.mix(net, *args)
        raw64 = net.double()(feats.double())
        net.float()
    print("fixture: float32 vs float64 PyTorch raw outputs, max abs difference %.3g"
          % (raw.double() - raw64).abs().max())
    tensors = {"input." + k: nhwc(planes[k]) for k in M.PLANES[:-1]}
    tensors.update({"output.features": nhwc(feats), "output.raw": nhwc(raw),
                    "output.alpha": nhwc(alpha)})
    write_weights(out_path, tensors, {
        "purpose": "PyTorch equivalence fixture of the mixing network (tests/mix/net_test.cpp)",
        "sample": os.path.relpath(sample_path, CACHE), "crop": [x0, y0, w, h],
        "layout": "NHWC", "weights": "models/mix.mcdnw",
        "weights_checksum": weights_checksum(state), "torch": torch.__version__})


def loss_description(cycles):
    """The loss of each cycle: SMAPE, plus the log-L1 term from the cycle that added it."""
    parts = []
    for c in cycles:
        w = c.get("log_l1_weight", 0)
        parts.append("steps %d-%d: SMAPE(z, r), eps 0.01%s" % (
            c["start"], c["start"] + c["steps"],
            " + %g mean|slog1p(z) - slog1p(r)|" % w if w else ""))
    return "; ".join(parts) or "SMAPE(z, reference), eps 0.01"


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--run-dir", default=os.path.join(CACHE, "mix", "run"))
    ap.add_argument("--out", default=os.path.join(ROOT, "models", "mix.mcdnw"))
    ap.add_argument("--note", default="", help="free text stored in the metadata (e.g. the "
                    "cycles of a checkpoint made before train.py recorded them)")
    ap.add_argument("--fixture", default=os.path.join(ROOT, "tests", "data", "mix", "mix_net_io.mcdnw"),
                    help="the C++ equivalence fixture to remake ('' for none: one fixture checks "
                         "the C++ forward, made from models/mix.mcdnw)")
    ap.add_argument("--denoiser", choices=("nfor", "cnn", "oidn"), default="nfor",
                    help="the denoiser this network mixes (the ops' mcdn:denoiser attribute; "
                         "cnn: export to models/mix_cnn.mcdnw, oidn: models/mix_oidn.mcdnw)")
    args = ap.parse_args()
    ck = torch.load(os.path.join(args.run_dir, "checkpoint.pt"))
    net = M.MixNet()
    net.load_state_dict(ck["model"])
    net.eval()
    state = {k: v.float() for k, v in net.state_dict().items()}
    st, targs = ck["state"], ck["args"]
    rows = list(csv.DictReader(open(os.path.join(args.run_dir, "loss.csv"))))
    last_val = [r for r in rows if r["val_smape"]][-1]
    recent = [float(r["train_smape"]) for r in rows[-8:]]
    train_files, val_files = ck["train_files"], ck["val_files"]
    crops = lambda files: sorted({f[:-12] for f in files})  # "full/0000_interior"
    metadata = {
        "network": "mix",
        "paper": "Firmino, Frisvad, Jensen 2022, Progressive Denoising of Monte Carlo Rendered Images, §4.3",
        "architecture": "conv1 5x5 18->48 ReLU; res1, res2: conv1 3x3 48 ReLU, conv2 3x3 48, "
                        "ReLU(x + r); out 3x3 48->9 (x1 RGB, x2 RGB, x3 RGB); "
                        "alpha = clip((x1 - x2) / max(x3, 1e-6), 0, 1)",
        "input_layout": M.INPUT_LAYOUT,
        "inputs": "HDR, DEN: sign(v) log(1 + |v|); VAR, SURE, sigma^2 f'(x), ||y - x||^2: "
                  "arctan(v / (y^2 + 0.01)), y = denoised; 18 channels, RGB each, in that order",
        "denoiser": "mcdntool --%s (defaults) --sure:probes=1" % args.denoiser
                    + (" (OIDN 2.x rt_hdr_alb_nrm weights, a user's own copy)" if args.denoiser == "oidn" else ""),
        "data": {"datasets": targs["datasets"], "train_files": len(train_files),
                 "train_crops": len(crops(train_files)), "validation_files": len(val_files),
                 "validation_crops": crops(val_files),
                 "levels_spp": sorted({int(f[-11:-7]) for f in train_files})},
        "training": {"steps": st["step"], "epochs": round(st.get("epochs", st["patches"] / max(len(train_files), 1)), 1),
                     "patches": st["patches"], "seconds": round(st["seconds"]),
                     "batch": targs["batch"], "patch": targs["patch"], "max_lr": targs["max_lr"],
                     "schedule": "one-cycle (torch OneCycleLR defaults), Adam",
                     "loss": loss_description(st.get("cycles", [])),
                     "swap": "HDR<->DEN, VAR<->SURE p=0.5",
                     "augmentation": "8 flips/rotations", "cycles": st.get("cycles", []),
                     "note": args.note},
        "final": {"train_smape_last200": round(float(np.mean(recent)), 5),
                  **{k: float(last_val[k]) for k in ("val_smape", "val_render_smape",
                     "val_denoised_smape", "val_relmse", "val_render_relmse",
                     "val_denoised_relmse") if last_val.get(k)}},
        "torch": torch.__version__,
    }
    os.makedirs(os.path.dirname(args.out), exist_ok=True)
    write_weights(args.out, state, metadata)
    for name in ("loss.csv", "loss.png"):
        src = os.path.join(args.run_dir, name)
        if os.path.exists(src):
            stem = os.path.splitext(os.path.basename(args.out))[0]  # mix_loss.csv, mix_cnn_loss.csv
            shutil.copyfile(src, os.path.join(os.path.dirname(args.out), stem + "_" + name))
    print(json.dumps(metadata, indent=1))
    print("wrote", args.out)
    if args.fixture:
        os.makedirs(os.path.dirname(args.fixture), exist_ok=True)
        prepared = os.path.join(CACHE, "mix", "prepared")
        sample = next((os.path.join(prepared, f) for f in val_files + train_files if "_0016spp" in f),
                      os.path.join(prepared, (val_files + train_files)[0]))
        write_fixture(net, state, sample, args.fixture)
        print("wrote", args.fixture)


if __name__ == "__main__":
    main()
