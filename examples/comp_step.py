#!/usr/bin/python3
"""A compositing pipeline step: denoise a Cycles render with NFOR, estimate its error with
SURE, mix it progressively with the render, and hand the ImageBuf on (here: write it).

    PYTHONPATH=build/python /usr/bin/python3 examples/comp_step.py examples/box out.exr
"""
import os
import sys

import OpenImageIO as oiio

import mcdenoise


def denoise_step(render_dir, stem="box_0016spp"):
    files = [(os.path.join(render_dir, f"{stem}{suffix}.exr"), kind)
             for suffix, kind in (("", "mean"), ("_var", "variance"),
                                  ("_A", "halfA"), ("_B", "halfB"))]
    render = mcdenoise.read_inputs(files)          # OpenImageIO.ImageBuf, every AOV merged
    mcdenoise.validate(render, preset="cycles")    # raises on NaN/Inf, naming file and channel
    features = mcdenoise.prefilter(render)         # NFOR §5.1
    with_error = mcdenoise.sure(features, denoiser="nfor")  # NFOR + its SURE error estimate
    return mcdenoise.mix(with_error, model="analytic")       # progressive mix (PD §4)


if __name__ == "__main__":
    render_dir = sys.argv[1] if len(sys.argv) > 1 else "examples/box"
    out = sys.argv[2] if len(sys.argv) > 2 else "denoised.exr"
    result = denoise_step(render_dir)
    reference = os.path.join(render_dir, "box_ref.exr")
    if os.path.exists(reference):
        print("relMSE", round(mcdenoise.metrics(result, oiio.ImageBuf(reference))["relmse"], 5))
    mcdenoise.write(result, out)
    print("wrote", out)
