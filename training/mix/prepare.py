#!/usr/bin/python3
"""Prepares the mixing network's training data (PD §4.3, §5.2): for every generated crop and
sample count, runs our denoiser and its SURE through mcdntool and stores what the network
reads and what the loss compares with.

    /usr/bin/python3 training/mix/prepare.py [--datasets full,small] [--denoiser nfor|cnn|oidn]
                                             [--watch MINUTES]

Reads   $CACHE/datasets/<set>/<crop>/<crop>_00NNspp{,_var,_A,_B}.exr and <crop>_ref.exr
        ($CACHE = $MCDN_CACHE or ~/.cache/mcdenoise; training/datagen makes them).
Writes  $CACHE/mix/prepared/<set>/<crop>_00NNspp.npz, float32 arrays [3, H, W]:
        x (render), y (NFOR), variance (of the mean of x), sure, divergence (sigma^2 f'(x)),
        residual (||y - x||^2), reference; plus spp. Written atomically; crops already
        prepared are skipped, so the script can be rerun (or left running with --watch) while
        the generator adds crops. With --denoiser cnn, y is the KPCN op's output (--cnn,
        models/kpcn.mcdnw) and the files go to $CACHE/mix/prepared/<set>.cnn/ (train.py
        --datasets full,small,full.cnn,small.cnn trains on both denoisers' outputs).
        With --denoiser oidn, y is OIDN's published network on our engine (--oidn, PD §6's
        configuration), its weights from $MCDN_OIDN_WEIGHTS, else ../shared/peers/oidn (a
        user's own copy: we never ship them); the files go to <set>.oidn/.
        With --denoiser blur, y is a deliberately biased "denoiser", the colour blurred by a
        Gaussian BLUR_WIDTHS[crop number % 2] pixels wide, and its SURE (mcdenoise.sure with
        a Python callable), into <set>.blur/: a network that only ever saw good denoisers
        learns to trust any denoiser (PD §4 wants the mix consistent for every one); the
        bench's --blur 5 stays a width it has not seen. Tried on 30 Nov and not used by the
        kept networks: it made them trust NFOR and the CNN less (models/README.md).

One mcdntool run per file:  -i X -i:as=variance X_var -i:as=halfA X_A -i:as=halfB X_B
--aov:preset=cycles --nfor --sure:probes=1 --ch <the 18 channels> -o tmp.exr
(NFOR with its defaults, SURE with K = 1 as PD §3.2 allows; ~2-4 s per 128x128 file.)
"""
import argparse
import glob
import os
import re
import subprocess
import sys
import tempfile
import time

import numpy as np
import OpenImageIO as oiio

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
CACHE = os.environ.get("MCDN_CACHE", os.path.expanduser("~/.cache/mcdenoise"))
MCDNTOOL = os.environ.get("MCDNTOOL", os.path.join(ROOT, "build", "bin", "mcdntool"))
OIDN_WEIGHTS = os.environ.get("MCDN_OIDN_WEIGHTS",
                              os.path.normpath(os.path.join(ROOT, "..", "shared", "peers", "oidn")))

# Widths of the blur "denoiser" (--denoiser blur), alternating by crop number; bench_mix
# --blur 5 measures between them.
BLUR_WIDTHS = (3, 9)

RGB = ("R", "G", "B")
COLOR = ["ViewLayer.Combined." + c for c in RGB]
# What mcdntool writes (mcdn::sure's channel names, lib/include/mcdn/sure.h) -> our keys.
PLANES = {
    "y": COLOR,
    "variance": ["variance.ViewLayer.Combined." + c for c in RGB],
    "x": ["noisy." + c for c in RGB],
    "sure": ["sure." + c for c in RGB],
    "divergence": ["sure.divergence." + c for c in RGB],
    "residual": ["sure.residual." + c for c in RGB],
}


def read_channels(path, names):
    """[len(names), H, W] float32 of the named channels of an EXR."""
    buf = oiio.ImageBuf(path)
    spec = buf.spec()
    pixels = buf.get_pixels(oiio.FLOAT)  # H, W, C
    if pixels is None or buf.has_error:
        raise RuntimeError("%s: %s" % (path, buf.geterror()))
    out = []
    for n in names:
        i = spec.channelindex(n)
        if i < 0:
            raise RuntimeError("%s: no channel '%s'" % (path, n))
        out.append(pixels[:, :, i])
    return np.stack(out).astype(np.float32)


def prepare_one(stem, reference, out_path, probes=1, denoiser="nfor"):
    """Runs the denoiser + SURE on the files of `stem` and writes out_path (.npz)."""
    all_channels = [c for names in PLANES.values() for c in names]
    with tempfile.TemporaryDirectory(prefix="mcdn_mix_") as tmp:
        exr = os.path.join(tmp, "sure.exr")
        cmd = [MCDNTOOL, "-i", stem + ".exr", "-i:as=variance", stem + "_var.exr",
               "-i:as=halfA", stem + "_A.exr", "-i:as=halfB", stem + "_B.exr",
               "--aov:preset=cycles",
               "--oidn:weights=" + OIDN_WEIGHTS if denoiser == "oidn" else "--" + denoiser,
               "--sure:probes=%d" % probes,
               "--ch", ",".join(all_channels), "-o", exr]
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            raise RuntimeError("mcdntool failed on %s: %s" % (stem, run.stderr.strip()[-500:]))
        planes = read_channels(exr, all_channels)
    arrays = {key: planes[3 * i:3 * i + 3] for i, key in enumerate(PLANES)}
    write_npz(arrays, stem, reference, out_path)


def blur_width(stem):
    return BLUR_WIDTHS[int(re.search(r"(\d+)_[a-z]+_\d+spp$", stem).group(1)) % 2]


def prepare_one_blur(stem, reference, out_path, probes=1):
    """As prepare_one, with the blur "denoiser" run through the Python module's sure."""
    python_dir = os.environ.get("MCDN_PYTHON", os.path.join(ROOT, "build", "python"))
    if python_dir not in sys.path:  # once, not once per file
        sys.path.insert(0, python_dir)
    import mcdenoise
    image = mcdenoise.read_inputs([(stem + ".exr", "mean"), (stem + "_var.exr", "variance"),
                                   (stem + "_A.exr", "halfA"), (stem + "_B.exr", "halfB")])
    kernel = oiio.ImageBufAlgo.make_kernel("gaussian", blur_width(stem), blur_width(stem))

    def blur(src):  # the colour blurred (edges clamp), every other channel as it is
        dst = src.copy(oiio.FLOAT)
        for name in COLOR:
            c = src.spec().channelindex(name)
            roi = oiio.ROI(src.roi.xbegin, src.roi.xend, src.roi.ybegin, src.roi.yend, 0, 1, c, c + 1)
            if not oiio.ImageBufAlgo.convolve(dst, src, kernel, True, roi):
                raise RuntimeError("blur: " + dst.geterror())
        return dst

    out = mcdenoise.sure(image, blur, probes=probes)
    pixels = out.get_pixels(oiio.FLOAT)
    spec = out.spec()
    arrays = {key: np.stack([pixels[:, :, spec.channelindex(n)] for n in names]).astype(np.float32)
              for key, names in PLANES.items()}
    write_npz(arrays, stem, reference, out_path)


def write_npz(arrays, stem, reference, out_path):
    arrays["reference"] = read_channels(reference, COLOR)
    arrays["spp"] = np.array(int(re.search(r"_(\d+)spp$", stem).group(1)), dtype=np.int32)
    tmp_path = out_path + ".tmp.npz"
    np.savez(tmp_path, **arrays)
    os.replace(tmp_path, out_path)


def todo(datasets, denoiser="nfor"):
    """(stem, reference, out_path) of every crop/level not yet prepared."""
    jobs = []
    for name in datasets:
        root = os.path.join(CACHE, "datasets", name)
        out_dir = os.path.join(CACHE, "mix", "prepared", name + ("" if denoiser == "nfor" else "." + denoiser))
        os.makedirs(out_dir, exist_ok=True)
        for crop_dir in sorted(glob.glob(os.path.join(root, "*", ""))):
            crop = os.path.basename(os.path.dirname(crop_dir))
            reference = os.path.join(crop_dir, crop + "_ref.exr")
            if not os.path.exists(reference):
                continue  # the generator writes the reference last: crop not finished
            for mean in sorted(glob.glob(os.path.join(crop_dir, crop + "_*spp.exr"))):
                stem = mean[:-4]
                if not all(os.path.exists(stem + s + ".exr") for s in ("_var", "_A", "_B")):
                    continue
                out_path = os.path.join(out_dir, os.path.basename(stem) + ".npz")
                if not os.path.exists(out_path):
                    jobs.append((stem, reference, out_path))
    return jobs


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--datasets", default="full,small")
    ap.add_argument("--probes", type=int, default=1, help="SURE's K (PD §3.2)")
    ap.add_argument("--denoiser", choices=("nfor", "cnn", "oidn", "blur"), default="nfor",
                    help="the mcdntool stage whose output the mix learns to combine (blur: "
                         "a biased stand-in, see above)")
    ap.add_argument("--watch", type=float, default=0,
                    help="keep rescanning for new crops for this many minutes")
    args = ap.parse_args()
    datasets = [d for d in args.datasets.split(",") if d]
    deadline = time.time() + 60 * args.watch
    done = 0
    while True:
        jobs = todo(datasets, args.denoiser)
        for stem, reference, out_path in jobs:
            t0 = time.time()
            try:
                if args.denoiser == "blur":
                    prepare_one_blur(stem, reference, out_path, args.probes)
                else:
                    prepare_one(stem, reference, out_path, args.probes, args.denoiser)
            except RuntimeError as e:
                print("prepare: %s" % e, file=sys.stderr, flush=True)
                continue
            done += 1
            print("%s  %.1f s" % (os.path.relpath(out_path, CACHE), time.time() - t0), flush=True)
        if time.time() >= deadline:
            break
        if not jobs:
            time.sleep(30)
    print("prepared %d files" % done)


if __name__ == "__main__":
    main()
