"""mcdntool --oidn against an independent PyTorch reading of OIDN's graph
(training/oidn/reference.py), on box at 16 and 256 spp and on a crop of a size that is no
multiple of 16 (the extension to the network's alignment); with prefilter=1 on box at 64 spp
and the crop. Exit 77 without ../shared's
weights or torch.

    pytorch_reference.py --mcdntool PATH --shared DIR
"""
import argparse
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
REFERENCE = os.path.join(HERE, "..", "..", "training", "oidn", "reference.py")


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--mcdntool", required=True)
    parser.add_argument("--shared", required=True)
    args = parser.parse_args()
    weights = os.path.join(args.shared, "peers", "oidn")
    box = os.path.join(args.shared, "data", "box")
    if not os.path.exists(os.path.join(weights, "rt_hdr_alb_nrm.tza")):
        print("skipped: no %s" % weights)
        return 77
    try:
        import torch  # noqa: F401
    except ImportError:
        print("skipped: no torch")
        return 77
    with tempfile.TemporaryDirectory() as tmp:
        crop = os.path.join(tmp, "crop.exr")
        subprocess.run(["oiiotool", os.path.join(box, "box_0016spp.exr"), "--cut",
                        "250x243+3+7", "-o", crop], check=True)
        # (render, prefilter=1): the features cleaned by OIDN's prefilters first.
        inputs = [(os.path.join(box, "box_0016spp.exr"), False),
                  (os.path.join(box, "box_0256spp.exr"), False), (crop, False),
                  (os.path.join(box, "box_0064spp.exr"), True), (crop, True)]
        for i, (render, prefilter) in enumerate(inputs):
            out = os.path.join(tmp, "out%d.exr" % i)
            stage = "--oidn:weights=" + weights + (":prefilter=1" if prefilter else "")
            subprocess.run([args.mcdntool, "-i", render, stage, "-o", out], check=True)
            code = subprocess.run([sys.executable, REFERENCE, "--weights", weights,
                                   "--input", render, "--engine", out]
                                  + (["--prefilter"] if prefilter else [])).returncode
            if code != 0:
                return code
    return 0


if __name__ == "__main__":
    sys.exit(main())
