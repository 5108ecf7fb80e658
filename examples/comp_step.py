#!/usr/bin/python3
"""A compositing pipeline step: denoise a render with the best chain its AOVs allow (with a
colour variance: the CNN, its SURE error estimate and the progressive mix), and hand the
ImageBuf on (here: write it).

    PYTHONPATH=build/python /usr/bin/python3 examples/comp_step.py examples/box out.exr
"""
import os
import sys

import OpenImageIO as oiio

import mcdenoise


def denoise_step(render_dir, stem="box_0016spp"):
    files = [(os.path.join(render_dir, f"{stem}{suffix}.exr"), kind)
             for suffix, kind in (("", "mean"), ("_var", "variance"))]
    render = mcdenoise.read_inputs(files)          # OpenImageIO.ImageBuf, every AOV merged
    mcdenoise.validate(render)                     # raises on NaN/Inf, naming file and channel
    print("denoise:", mcdenoise.plan(render))      # which chain, and why
    return mcdenoise.denoise(render)


if __name__ == "__main__":
    render_dir = sys.argv[1] if len(sys.argv) > 1 else "examples/box"
    out = sys.argv[2] if len(sys.argv) > 2 else "denoised.exr"
    result = denoise_step(render_dir)
    reference = os.path.join(render_dir, "box_ref.exr")
    if os.path.exists(reference):
        print("relMSE", round(mcdenoise.metrics(result, oiio.ImageBuf(reference))["relmse"], 5))
    mcdenoise.write(result, out)
    print("wrote", out)
