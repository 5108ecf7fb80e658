"""Combine K independent seed renders into mean, variance-of-mean and half buffers A/B.

Same layout and metadata as ../shared/data/box: for seeds x_1..x_K (each N/K spp)
  mean = (1/K) sum x_k                    -> <stem>.exr
  var  = sample variance (ddof=1) / K     -> <stem>_var.exr   (variance OF THE MEAN)
  A, B = mean of seeds 1..K/2, K/2+1..K   -> <stem>_A.exr, <stem>_B.exr
for every channel.  Float32, zip, Blender's multilayer channel names and order.
"""
import os

import numpy as np
import OpenImageIO as oiio


def read_exr(path):
    buf = oiio.ImageBuf(path)
    if buf.has_error:
        raise IOError(f"{path}: {buf.geterror()}")
    spec = buf.spec()
    px = buf.get_pixels(oiio.FLOAT)
    if px is None:
        raise IOError(f"{path}: cannot read pixels")
    return px.reshape(spec.height, spec.width, spec.nchannels), list(spec.channelnames)


def write_exr(path, px, names, attrs):
    h, w, c = px.shape
    spec = oiio.ImageSpec(w, h, c, oiio.FLOAT)
    spec.channelnames = tuple(names)
    spec.attribute("compression", "zip")
    spec.attribute("oiio:ColorSpace", "Linear")
    for k, v in attrs.items():
        spec.attribute(k, v)
    out = oiio.ImageOutput.create(path)
    if out is None:
        raise IOError(f"cannot create {path}: {oiio.geterror()}")
    tmp = path + ".part.exr"
    out.open(tmp, spec)
    out.write_image(np.ascontiguousarray(px, dtype=np.float32))
    out.close()
    os.replace(tmp, path)


def combine(inputs, stem, extra_attrs=None, halves=True, suffix=".exr"):
    """inputs: list of seed EXR paths (K >= 2). Writes stem.exr, stem_var.exr, [stem_A/_B.exr];
    suffix replaces ".exr" (a frame of a sequence: ".0001.exr" -> stem_var.0001.exr, ...)."""
    k = len(inputs)
    if k < 2:
        raise ValueError("need at least two seeds for a variance")
    imgs, names = [], None
    for p in inputs:
        px, n = read_exr(p)
        if names is None:
            names = n
        elif n != names:
            raise ValueError(f"{p}: channel list differs from {inputs[0]}")
        imgs.append(px.astype(np.float64))
    stack = np.stack(imgs)
    mean = stack.mean(axis=0)
    var = stack.var(axis=0, ddof=1) / k
    attrs = {"combine:inputs": ",".join(os.path.basename(p) for p in inputs), "combine:K": str(k)}
    attrs.update(extra_attrs or {})
    write_exr(stem + suffix, mean, names, attrs)
    write_exr(stem + "_var" + suffix, var, names, attrs)
    out = {"mean": stem + suffix, "var": stem + "_var" + suffix}
    if halves:
        h = k // 2
        for tag, part in (("A", stack[:h]), ("B", stack[h:2 * h])):
            a = dict(attrs)
            a["half"] = tag
            a["K_half"] = str(h)
            write_exr(f"{stem}_{tag}{suffix}", part.mean(axis=0), names, a)
            out[tag] = f"{stem}_{tag}{suffix}"
    return out
