"""Running one chain on one render as a child mcdntool process, and measuring it.

Time: the child's wall time (start to exit: reading, denoising, writing) and its stage time
(the sum of mcdntool -v's "STAGE WxH done in S s" lines: the denoising alone), each also as a
ratio to a baseline op timed in this process just before the child (OIIO's 19x19 box
convolution of a 256x256 RGB image, as bench_nfor), so ratios survive a busy machine.
Memory: the child's peak RSS (wait4's rusage, measure_child.py). Error: a second, untimed mcdntool reads the
result and prints our metrics (lib/include/mcdn/metrics.h) and writes the relMSE heatmap.
"""
import json
import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass

import OpenImageIO as oiio


@dataclass
class Chain:
    name: str
    commands: list    # mcdntool commands between the inputs and -o
    mixes: bool = False

    @property
    def file_name(self):
        return re.sub(r"[^A-Za-z0-9]+", "_", self.name).strip("_")


OIDN_WEIGHTS = os.path.join(os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__)))),
                            "..", "shared", "peers", "oidn")


def has_oidn_weights():
    return os.path.exists(os.path.join(OIDN_WEIGHTS, "rt_hdr_alb_nrm.tza"))


CHAINS = [
    Chain("noisy", []),  # the render passed through: read and write only
    Chain("nfor", ["--prefilter", "--nfor"]),
    Chain("cnn", ["--cnn"]),
    Chain("nfor+sure+mix:analytic", ["--prefilter", "--nfor", "--sure", "--mix:model=analytic:alpha=1"], True),
    Chain("nfor+sure+mix:net", ["--prefilter", "--nfor", "--sure", "--mix:model=net:alpha=1"], True),
    Chain("cnn+sure+mix:analytic", ["--cnn", "--sure", "--mix:model=analytic:alpha=1"], True),
    Chain("cnn+sure+mix:net", ["--cnn", "--sure", "--mix:model=net:alpha=1"], True),
    # Intel Open Image Denoise's published network on our engine, with the weights of
    # ../shared/peers/oidn (measurement only, never part of the project): skipped without them.
    Chain("oidn", ["--oidn:weights=" + OIDN_WEIGHTS]),
    Chain("oidn+sure+mix:net", ["--oidn:weights=" + OIDN_WEIGHTS, "--sure",
                                "--mix:model=net:alpha=1"], True),
    # Our CNN beside OIDN, weighed per pixel by their SURE (--choose:with=cnn), then the mix.
    Chain("oidn+sure+choose:cnn+mix:net", ["--oidn:weights=" + OIDN_WEIGHTS, "--sure",
                                           "--choose:with=cnn", "--mix:model=net:alpha=1"], True),
    # The plan a user gets by default: with $MCDN_OIDN_WEIGHTS set, over OIDN's network.
    Chain("denoise", ["--denoise"]),
    # OIDN with its albedo and normal prefilters (Blender's "Accurate"), and the mix over it.
    Chain("oidn:prefilter", ["--oidn:weights=" + OIDN_WEIGHTS + ":prefilter=1"]),
    Chain("oidn:prefilter+sure+mix:net", ["--oidn:weights=" + OIDN_WEIGHTS + ":prefilter=1",
                                          "--sure", "--mix:model=net:alpha=1"], True),
]
ALPHA_CHANNELS = ["mix.alpha.R", "mix.alpha.G", "mix.alpha.B"]
MEASURE_CHILD = os.path.join(os.path.dirname(os.path.abspath(__file__)), "measure_child.py")
STAGE_LINE = re.compile(r"mcdntool: (\S+) \d+x\d+ done in ([0-9.]+) s")


class Baseline:
    """The fixed op every time is also given relative to: 19x19 box convolution (361
    multiply-adds per pixel and channel) of a fixed 256x256x3 float image, best of 3."""

    def __init__(self, nthreads):
        self.nthreads = nthreads
        self.image = oiio.ImageBuf(oiio.ImageSpec(256, 256, 3, "float"))
        oiio.ImageBufAlgo.noise(self.image, "uniform", 0.0, 1.0, False, 1)
        self.kernel = oiio.ImageBufAlgo.make_kernel("box", 19, 19)

    def seconds(self):
        best = float("inf")
        for _ in range(3):
            start = time.perf_counter()
            oiio.ImageBufAlgo.convolve(self.image, self.kernel, True, nthreads=self.nthreads)
            best = min(best, time.perf_counter() - start)
        return best


def run_child(argv, log_path):
    """Runs argv with stdout+stderr into log_path, through measure_child.py (see there why):
    (exit code, wall s, CPU s, peak RSS MB)."""
    launcher = [sys.executable, "-S", MEASURE_CHILD, log_path, "--"]
    result = json.loads(subprocess.run(launcher + argv, capture_output=True, text=True, check=True).stdout)
    return result["exit"], result["wall_s"], result["cpu_s"], result["peak_rss_mb"]


def last_line(path):
    with open(path) as f:
        lines = [line.strip() for line in f if line.strip()]
    return lines[-1] if lines else ""


class Runner:
    """Runs chains with one mcdntool and thread count; writes under `out`."""

    def __init__(self, mcdntool, out, nthreads):
        self.mcdntool = mcdntool
        self.out = out
        self.nthreads = nthreads
        self.baseline = Baseline(nthreads)
        for sub in ("work", "logs", "images"):
            os.makedirs(os.path.join(out, sub), exist_ok=True)

    def input_args(self, render):
        args = []
        for path, kind in render.inputs:
            args += ["-i" if kind == "mean" else f"-i:as={kind}", path]
        return args + [f"--aov:preset={render.preset}"]

    def run(self, render, chain, images=True):
        """One row of the CSV: the chain on the render, timed, then measured."""
        tag = f"{render.key}_{chain.file_name}"
        result_exr = os.path.join(self.out, "work", tag + ".exr")
        log = os.path.join(self.out, "logs", tag + ".log")
        channels = render.color_channels() + (ALPHA_CHANNELS if chain.mixes else [])
        argv = ([self.mcdntool, "-v", "--threads", str(self.nthreads)] + self.input_args(render)
                + chain.commands + ["--ch", ",".join(channels), "-o:datatype=float", result_exr])
        baseline_s = self.baseline.seconds()
        code, wall, cpu, rss = run_child(argv, log)
        row = {"group": render.group, "scene": render.scene, "spp": render.spp,
               "width": render.width, "height": render.height, "pixels": render.pixels,
               "chain": chain.name, "threads": self.nthreads, "wall_s": wall, "cpu_s": cpu,
               "baseline_s": baseline_s, "wall_x_baseline": wall / baseline_s,
               "peak_rss_mb": rss, "status": "ok"}
        with open(log) as f:
            stages = STAGE_LINE.findall(f.read())
        row["stage_s"] = sum(float(s) for _, s in stages)
        row["stage_x_baseline"] = row["stage_s"] / baseline_s
        row["stages"] = " ".join(f"{name}={float(s):.3f}" for name, s in stages)
        if code != 0:
            row["status"] = f"exit {code}: {last_line(log)}"
            return row
        self.measure(row, render, chain, result_exr, tag, images)
        os.remove(result_exr)
        return row

    def measure(self, row, render, chain, result_exr, tag, images):
        """Metrics (and the heatmap, the result's preview and the alpha' map) of a result."""
        image_dir = os.path.join(self.out, "images", render.key)
        os.makedirs(image_dir, exist_ok=True)
        heatmap = os.path.join(image_dir, chain.file_name + "_relmse.png")
        argv = [self.mcdntool, "--threads", str(self.nthreads), "-i", result_exr,
                f"--aov:preset={render.preset}", "--metrics:format=json", render.reference]
        if images:
            argv += ["--heatmap:metric=relmse:min=-4:max=0", heatmap]
        log = os.path.join(self.out, "logs", tag + "_metrics.log")
        code, _, _, _ = run_child(argv, log)
        metrics = None
        with open(log) as f:
            for line in f:
                if line.startswith("{"):
                    metrics = json.loads(line)
        if code != 0 or metrics is None:
            row["status"] = f"metrics failed: {last_line(log)}"
            return
        for key in ("relmse", "rmse", "smape", "ssim", "psnr", "mse"):
            row[key] = metrics[key]
        result = oiio.ImageBuf(result_exr)
        if chain.mixes:
            alpha = mean_of_channels(result, ALPHA_CHANNELS)
            row["alpha_mean"] = oiio.ImageBufAlgo.computePixelStats(alpha).avg[0]
            if images:
                write_png(oiio.ImageBufAlgo.color_map(alpha, 0, "viridis"),
                          os.path.join(image_dir, chain.file_name + "_alpha.png"))
        if images:
            write_png(display(result, render.color_channels()),
                      os.path.join(image_dir, chain.file_name + ".png"))
            reference_png = os.path.join(image_dir, "reference.png")
            if not os.path.exists(reference_png):
                reference = oiio.ImageBuf(render.reference)
                names = render.color_channels()
                if reference.spec().channelindex(names[0]) < 0:
                    names = ["R", "G", "B"]
                write_png(display(reference, names), reference_png)


def mean_of_channels(image, names):
    """One channel: the mean of the named channels."""
    picked = oiio.ImageBufAlgo.channels(image, tuple(names))
    return oiio.ImageBufAlgo.channel_sum(picked, tuple([1.0 / len(names)] * len(names)))


def display(image, names):
    """A viewable picture of scene-linear colour: clamp to [0, 1], then gamma 1/2.2."""
    colour = oiio.ImageBufAlgo.channels(image, tuple(names), newchannelnames=("R", "G", "B"))
    colour = oiio.ImageBufAlgo.clamp(colour, 0.0, 1.0)
    return oiio.ImageBufAlgo.pow(colour, 1.0 / 2.2)


def write_png(image, path):
    if not image.write(path, "uint8"):
        raise RuntimeError(f"{path}: {image.geterror()}")
