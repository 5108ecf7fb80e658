"""Reads a Cycles render (the layout of ../shared/data/box and training/datagen) into the raw
planes of model.py, exactly as lib/src/cnn/cnn_inputs.cpp does for the cycles preset:

    diffuse  = DiffCol * (DiffDir + DiffInd)                       (KPCN §4.3, Cycles passes)
    specular = Combined - diffuse   (glossy, transmission, emission, environment)
    demod    = DiffCol              (the albedo divided out of the diffuse part)
    features = Denoising Albedo / Normal / Depth

Variances of the products are not in the files; we use the delta method with the passes
taken as independent (documented in models/README-kpcn.md):
    Var[C (D + I)] ~ C^2 (Var D + Var I) + (D + I)^2 Var C
and Var[specular] = the same sum over the glossy and transmission products + Var Emit + Var Env.
"""
import os

import numpy as np

RGB = ("R", "G", "B")
PRODUCTS_DIFFUSE = [("DiffCol", "DiffDir", "DiffInd")]
PRODUCTS_SPECULAR = [("GlossCol", "GlossDir", "GlossInd"), ("TransCol", "TransDir", "TransInd")]
ADDED_SPECULAR = ["Emit", "Env"]


def read_exr(path):
    """{channel name: [H, W] float32}: the file as it is now (ImageInput, not ImageBuf: the
    image cache would hand back what an earlier read of the same path saw, and bench/families
    rewrites one output file per chain)."""
    import OpenImageIO as oiio  # here: a GPU machine training from the patch set has none
    image = oiio.ImageInput.open(path)
    if image is None:
        raise RuntimeError("%s: %s" % (path, oiio.geterror()))
    try:
        pixels = image.read_image(oiio.FLOAT)
        if pixels is None:
            raise RuntimeError("%s: %s" % (path, image.geterror()))
        names = image.spec().channelnames
    finally:
        image.close()
    pixels = pixels.reshape(pixels.shape[0], pixels.shape[1], -1)
    return {n: np.ascontiguousarray(pixels[:, :, i]) for i, n in enumerate(names)}


def _layer(channels):
    for n in channels:
        if n.endswith(".Combined.R"):
            return n[:-len("Combined.R")]
    raise RuntimeError("no Combined pass")


def _pass(channels, layer, name, suffixes=RGB):
    keys = [layer + name + "." + s for s in suffixes]
    if not all(k in channels for k in keys):
        return None
    return np.stack([np.nan_to_num(channels[k].astype(np.float32)) for k in keys])


def _products(mean, var, layer, products, added):
    value = 0
    variance = 0
    for colour, direct, indirect in products:
        c, d, i = (_pass(mean, layer, p) for p in (colour, direct, indirect))
        if c is None or d is None or i is None:
            continue
        vc, vd, vi = (_pass(var, layer, p) for p in (colour, direct, indirect))
        light = d + i
        value = value + c * light
        variance = variance + c * c * (np.maximum(vd, 0) + np.maximum(vi, 0)) \
            + light * light * np.maximum(vc, 0)
    for p in added:
        vp = _pass(var, layer, p)
        if vp is not None:
            variance = variance + np.maximum(vp, 0)
    return value, variance


def load_render(prefix, spp=None):
    """Raw planes (numpy, float32) of `<prefix>_00NNspp.exr` + `_var.exr`, or of a render
    given as a path. Depth is left unscaled (model.scale_depth does it)."""
    path = prefix if spp is None else "%s_%04dspp.exr" % (prefix, spp)
    mean = read_exr(path)
    var = read_exr(path[:-4] + "_var.exr")
    layer = _layer(mean)
    raw = {"color": _pass(mean, layer, "Combined"),
           "color_var": np.maximum(_pass(var, layer, "Combined"), 0)}
    diffuse, diffuse_var = _products(mean, var, layer, PRODUCTS_DIFFUSE, [])
    _, specular_var = _products(mean, var, layer, PRODUCTS_SPECULAR, ADDED_SPECULAR)
    raw["diffuse"] = diffuse.astype(np.float32)
    raw["diffuse_var"] = diffuse_var.astype(np.float32)
    raw["specular"] = raw["color"] - raw["diffuse"]
    raw["specular_var"] = np.asarray(specular_var, np.float32) * np.ones_like(raw["color"])
    raw["demod"] = _pass(mean, layer, "DiffCol")
    raw["albedo"] = _pass(mean, layer, "Denoising Albedo")
    raw["albedo_var"] = np.maximum(_pass(var, layer, "Denoising Albedo"), 0)
    raw["normal"] = _pass(mean, layer, "Denoising Normal", ("X", "Y", "Z"))
    raw["normal_var"] = np.maximum(_pass(var, layer, "Denoising Normal", ("X", "Y", "Z")), 0)
    raw["depth"] = _pass(mean, layer, "Denoising Depth", ("Z",))
    raw["depth_var"] = np.maximum(_pass(var, layer, "Denoising Depth", ("Z",)), 0)
    return raw


def load_reference(path):
    """(colour, diffuse, specular) of a reference render, [3, H, W] each."""
    mean = read_exr(path)
    layer = _layer(mean)
    colour = _pass(mean, layer, "Combined")
    diffuse = 0
    for c, d, i in PRODUCTS_DIFFUSE:
        diffuse = diffuse + _pass(mean, layer, c) * (_pass(mean, layer, d) + _pass(mean, layer, i))
    return colour, diffuse.astype(np.float32), colour - diffuse


def crops(dataset_dir):
    """Crop directories that are complete (have crop.json), sorted."""
    if not os.path.isdir(dataset_dir):
        return []
    out = []
    for name in sorted(os.listdir(dataset_dir)):
        d = os.path.join(dataset_dir, name)
        if os.path.isfile(os.path.join(d, "crop.json")):
            out.append(d)
    return out


def load_reference_variance(path):
    """The variance of the mean of a reference's (or target's) colour, [3, H, W]."""
    var = read_exr(path)
    return np.maximum(_pass(var, _layer(var), "Combined"), 0)
