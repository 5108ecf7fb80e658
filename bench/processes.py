"""Whole mcdntool processes as a benchmark sees them (bench/production, bench/skip_frames,
bench/caustics), and our metrics of their results."""
import json
import os
import subprocess


def measure(command, memory_gb, log, band_pixels=None, oidn_weights=None):
    """(wall s, user s, sys s, peak RSS MB, ok) of one child process under /usr/bin/time,
    capped at memory_gb of address space so that an unbounded run fails instead of taking
    the machine; its output goes to `log`. oidn_weights, when given, is its MCDN_OIDN_WEIGHTS
    (--denoise then runs OIDN's plan; "": unset, our CNN's plan)."""
    env = dict(os.environ)
    env.pop("MCDN_BAND_PIXELS", None)
    if band_pixels is not None:
        env["MCDN_BAND_PIXELS"] = str(band_pixels)
    if oidn_weights is not None:
        env.pop("MCDN_OIDN_WEIGHTS", None)
        if oidn_weights:
            env["MCDN_OIDN_WEIGHTS"] = oidn_weights
    timing = log + ".time"
    full = ["prlimit", f"--as={int(memory_gb * 2**30)}", "/usr/bin/time", "-f", "%e %U %S %M",
            "-o", timing] + command
    with open(log, "w") as out:
        ok = subprocess.run(full, stdout=out, stderr=subprocess.STDOUT, env=env).returncode == 0
    wall, user, sys_s, rss_kb = open(timing).read().split()[-4:]
    return float(wall), float(user), float(sys_s), int(rss_kb) / 1024, ok


def metrics(tool, path, reference, trim=False):
    """mcdntool --metrics of path's colour against reference (trim: the 0.01% best and worst
    pixels dropped), as a dict: relmse, rmse, smape, ssim, ..."""
    out = subprocess.run([tool, "-i", path, f"--metrics:format=json:trim={int(trim)}", reference],
                         check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])
