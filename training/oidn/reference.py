"""An independent reading of Open Image Denoise's published UNet in PyTorch, from the public
facts alone (../shared/peers/oidn/README.md: the tensor archive's layout, the graph, the
input transforms), to check our engine's `--oidn` against: never OIDN's code.

    reference.py --weights DIR --input RENDER.exr --engine OUT.exr [--tolerance 1e-3]
                 [--prefilter]

Runs the reading on RENDER's colour, albedo and normal (Blender's Combined, Denoising Albedo
and Denoising Normal, or R,G,B only), and compares with OUT (mcdntool --oidn's result;
with --prefilter, --oidn:prefilter=1's: the albedo and normal first through OIDN's networks
for them, rt_alb and rt_nrm, then rt_hdr_calb_cnrm):
relative RMS of the difference over the frame, exit 1 above the tolerance. Exit 77 (skipped)
without torch or the weights.
"""
import argparse
import math
import os
import struct
import sys

import numpy as np


def read_tza(path):
    """{name: float32 array} of a tensor archive."""
    data = open(path, "rb").read()
    magic, major, _minor, table = struct.unpack_from("<HBBQ", data, 0)
    if magic != 0x41D7 or major != 2:
        raise ValueError("%s: not a tensor archive" % path)
    (count,) = struct.unpack_from("<I", data, table)
    at = table + 4
    tensors = {}
    for _ in range(count):
        (length,) = struct.unpack_from("<H", data, at)
        name = data[at + 2:at + 2 + length].decode()
        at += 2 + length
        rank = data[at]
        dims = struct.unpack_from("<%dI" % rank, data, at + 1)
        at += 1 + 4 * rank + rank  # dims, then the layout letters
        kind = chr(data[at])
        (offset,) = struct.unpack_from("<Q", data, at + 1)
        at += 9
        dtype = np.float16 if kind == "h" else np.float32
        n = int(np.prod(dims))
        tensors[name] = np.frombuffer(data, dtype, n, offset).astype(np.float32).reshape(dims)
    return tensors


def unet(x, w, torch):
    """The UNet of the facts: 3x3 convs + ReLU, pools after enc_conv1-4, nearest upsampling
    joined by pool3/2/1 and the input (the upsampled channels first)."""
    F = torch.nn.functional

    def conv(x, name):
        return F.relu(F.conv2d(x, torch.from_numpy(w[name + ".weight"]),
                               torch.from_numpy(w[name + ".bias"]), padding=1))

    up = lambda t: F.interpolate(t, scale_factor=2, mode="nearest")
    inp = x
    x = conv(x, "enc_conv0")
    pools = []
    for level in range(1, 5):
        x = F.max_pool2d(conv(x, "enc_conv%d" % level), 2)
        pools.append(x)
    x = conv(conv(x, "enc_conv5a"), "enc_conv5b")
    for level, skip in zip((4, 3, 2), (pools[2], pools[1], pools[0])):
        x = torch.cat([up(x), skip], 1)
        x = conv(conv(x, "dec_conv%da" % level), "dec_conv%db" % level)
    x = torch.cat([up(x), inp], 1)
    x = conv(conv(x, "dec_conv1a"), "dec_conv1b")
    return conv(x, "dec_conv0")


# The PU transfer function's fit and its normalisation (README: normalised at 65504).
PU = dict(a=1.41283765e+03, b=1.64593172e+00, c=4.31384981e-01, d=-2.94139609e-03,
          e=1.92653254e-01, f=6.26026094e-03, g=9.98620152e-01, y0=1.57945760e-06,
          y1=3.22087631e-02, x0=2.23151711e-03, x1=3.70974749e-01)


def pu(y):
    p = PU
    return np.where(y <= p["y0"], p["a"] * y,
                    np.where(y <= p["y1"], p["b"] * np.power(np.maximum(y, 1e-30), p["c"]) + p["d"],
                             p["e"] * np.log(y + p["f"]) + p["g"]))


def pu_inverse(x):
    p = PU
    return np.where(x <= p["x0"], x / p["a"],
                    np.where(x <= p["x1"], np.power(np.maximum((x - p["d"]) / p["b"], 0), 1 / p["c"]),
                             np.exp((x - p["g"]) / p["e"]) - p["f"]))


def srgb(y):
    """The sRGB curve (OIDN's low-dynamic-range transfer, the albedo prefilter's)."""
    return np.where(y <= 0.0031308, 12.92 * y, 1.055 * np.power(np.maximum(y, 0), 1 / 2.4) - 0.055)


def srgb_inverse(x):
    return np.where(x <= 0.04045, x / 12.92, np.power((np.maximum(x, 0) + 0.055) / 1.055, 2.4))


def run_unet(x, weights, torch):
    """The UNet on an H x W x C image, extended by its last rows and columns to a multiple
    of 16 and cut back."""
    h, w, _ = x.shape
    x = np.pad(x, ((0, -h % 16), (0, -w % 16), (0, 0)), mode="edge")
    with torch.no_grad():
        y = unet(torch.from_numpy(x.transpose(2, 0, 1)[None].astype(np.float32)), weights, torch)
    return y[0].numpy().transpose(1, 2, 0)[:h, :w].astype(np.float64)


def prefiltered(albedo, normal, folder, torch):
    """The albedo and normal cleaned by rt_alb (in and out through the sRGB curve on [0, 1])
    and rt_nrm ([-1, 1] mapped to [0, 1] and back)."""
    a = run_unet(srgb(np.clip(albedo, 0, 1)), read_tza(os.path.join(folder, "rt_alb.tza")), torch)
    n = run_unet(np.clip(normal, -1, 1) * 0.5 + 0.5, read_tza(os.path.join(folder, "rt_nrm.tza")), torch)
    return (np.minimum(srgb_inverse(np.maximum(a, 0)), 1),
            np.minimum(np.maximum(n, 0), 1) * 2 - 1)


def autoexposure(rgb):
    """0.18 over the geometric mean of the mean luminances of ~16x16-pixel bins."""
    h, w, _ = rgb.shape
    lum = np.clip(np.nan_to_num(rgb), 0, None) @ np.array([0.212671, 0.715160, 0.072169])
    nby, nbx = (h + 15) // 16, (w + 15) // 16
    logs = []
    for by in range(nby):
        for bx in range(nbx):
            b = lum[by * h // nby:(by + 1) * h // nby, bx * w // nbx:(bx + 1) * w // nbx].mean()
            if b > 1e-8:
                logs.append(math.log2(b))
    return 0.18 / 2 ** (sum(logs) / len(logs)) if logs else 1.0


def channels(image, names):
    spec = image.spec()
    index = [spec.channelindex(n) for n in names]
    if min(index) < 0:
        return None
    pixels = image.get_pixels()
    return np.stack([pixels[..., i] for i in index], -1).astype(np.float64)


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--weights", required=True)
    parser.add_argument("--input", required=True)
    parser.add_argument("--engine", required=True)
    parser.add_argument("--tolerance", type=float, default=1e-3)
    parser.add_argument("--prefilter", action="store_true")
    args = parser.parse_args()
    try:
        import torch
        import OpenImageIO as oiio
    except ImportError as e:
        print("skipped: %s" % e)
        return 77
    if not os.path.isdir(args.weights):
        print("skipped: no %s" % args.weights)
        return 77
    render = oiio.ImageBuf(args.input)
    layer = "ViewLayer."
    colour = channels(render, [layer + "Combined." + c for c in "RGB"])
    albedo = channels(render, [layer + "Denoising Albedo." + c for c in "RGB"])
    normal = channels(render, [layer + "Denoising Normal." + c for c in "XYZ"])
    if colour is None:
        colour, albedo, normal = channels(render, ["R", "G", "B"]), None, None
    model = "rt_hdr" + ("_alb" if albedo is not None else "") + \
        ("_nrm" if albedo is not None and normal is not None else "")
    if args.prefilter:
        if model != "rt_hdr_alb_nrm":
            print("%s: --prefilter needs an albedo and a normal" % args.input)
            return 2
        albedo, normal = prefiltered(albedo, normal, args.weights, torch)
        model = "rt_hdr_calb_cnrm"
    weights = read_tza(os.path.join(args.weights, model + ".tza"))
    scale = autoexposure(colour)
    norm = 1 / pu(np.float64(65504))
    planes = [pu(np.clip(np.nan_to_num(colour) * scale, 0, None)) * norm]
    if albedo is not None:
        planes.append(np.clip(albedo, 0, 1))
        if normal is not None:
            planes.append(np.clip(normal, -1, 1) * 0.5 + 0.5)
    y = run_unet(np.concatenate(planes, -1), weights, torch)
    ours = pu_inverse(np.maximum(y, 0) / norm) / scale
    engine = channels(oiio.ImageBuf(args.engine), [layer + "Combined." + c for c in "RGB"])
    if engine is None:
        engine = channels(oiio.ImageBuf(args.engine), ["R", "G", "B"])
    rel = math.sqrt(np.mean((engine - ours) ** 2) / np.mean(ours ** 2))
    print("%s (%s): relative RMS of engine - reading %.2e (tolerance %.0e)"
          % (args.input, model, rel, args.tolerance))
    return 0 if rel <= args.tolerance else 1


if __name__ == "__main__":
    sys.exit(main())
