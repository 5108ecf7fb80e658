"""KPCN (Bako et al. 2017, ../shared/papers/kpcn-bako-2017.md) sized for CPUs: the input
transforms of §4.3/§5.1, the per-branch network and the reconstruction of eq. 4. Shared by
train.py, export.py and evaluate.py; lib/src/cnn/ computes exactly the same (the fixture test
tests/cnn/pytorch_test.cpp runs the whole op against `denoise` below).

Raw planes (what the loader reads from one render, all [C, H, W] float32):
    color, color_var           Combined and the variance of its mean (3 + 3)
    diffuse, diffuse_var       DiffCol*(DiffDir+DiffInd) and its delta-method variance
    specular, specular_var     color - diffuse, variance of the remaining passes
    demod                      the albedo divided out of the diffuse part (DiffCol)
    albedo, albedo_var         feature albedo (Denoising Albedo) and its variance
    normal, normal_var         feature normal (camera space)
    depth, depth_var           feature depth (1 channel each), unscaled

Network input of a branch (34 channels, INPUT_LAYOUT):
    0-2   colour in the network domain: log(1 + irradiance) (diffuse), log(1 + specular)
    3     log(1 + mean over RGB of that colour's variance), variance moved to the network
          domain by the Taylor rule of §5.1 (Var h(X) ~ h'(mu)^2 Var X)
    4-6   log(1 + albedo)       7-9 normal       10 depth scaled to [0, 1] over the frame
    11-13 log(1 + mean variance) of albedo, normal, depth (depth variance scaled like depth)
    14-23 x gradients of channels 0-2 and 4-10 (forward differences, 0 in the last column)
    24-33 y gradients of the same
every value made finite and clamped to +-INPUT_LIMIT.
"""
import torch
import torch.nn as nn
import torch.nn.functional as F

import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "common"))
from nn_ops import apply_kernel  # noqa: E402

INPUT_LAYOUT = "kpcn-cpu-1"
INPUT_CHANNELS = 34
ALBEDO_EPSILON = 0.00316  # §4.3
INPUT_LIMIT = 1e3
KERNEL = 5                # each reconstruction step: a 5x5 softmax kernel (eq. 9)
ITERATIONS = 5            # 5 steps of 5x5 reach 21x21, the paper's k = 21
WIDTHS = (16, 32, 48)     # UNet widths at full, 1/2 and 1/4 resolution (one per level)


def _gradients(planes):
    """Forward differences along x and y, zero in the last column / row (N, C, H, W)."""
    gx = torch.zeros_like(planes)
    gy = torch.zeros_like(planes)
    gx[..., :, :-1] = planes[..., :, 1:] - planes[..., :, :-1]
    gy[..., :-1, :] = planes[..., 1:, :] - planes[..., :-1, :]
    return gx, gy


def _finite(t):
    return torch.clamp(torch.nan_to_num(t, nan=0.0, posinf=INPUT_LIMIT, neginf=-INPUT_LIMIT),
                       -INPUT_LIMIT, INPUT_LIMIT)


def scale_depth(depth, depth_var):
    """§5.1: depth scaled linearly to [0, 1] over the frame (one image, [1, H, W])."""
    lo, hi = float(depth.min()), float(depth.max())
    span = hi - lo
    if not span > 0:
        return torch.zeros_like(depth), torch.zeros_like(depth_var)
    return (depth - lo) / span, depth_var / (span * span)


def branch_inputs(raw):
    """Network inputs of both branches from raw planes (batched, N, C, H, W; depth already
    scaled by scale_depth). Returns {branch: (features, image)} where `image` is what the
    predicted kernels filter: irradiance (diffuse), log(1 + specular)."""
    eps = ALBEDO_EPSILON
    relu = torch.relu
    demod = relu(raw["demod"]) + eps
    irradiance = relu(raw["diffuse"]) / demod
    irradiance_var = raw["diffuse_var"] / (demod * demod)            # §5.1 eq. 5 (divided)
    specular = relu(raw["specular"])
    log_specular = torch.log1p(specular)
    log_specular_var = raw["specular_var"] / ((1 + specular) ** 2)   # d log(1+x) = dx/(1+x)

    log_irradiance = torch.log1p(irradiance)
    log_irradiance_var = irradiance_var / ((1 + irradiance) ** 2)

    albedo = torch.log1p(relu(raw["albedo"]))
    normal = raw["normal"]
    depth = raw["depth"]
    feature_var = torch.cat([raw["albedo_var"].mean(1, keepdim=True),
                             raw["normal_var"].mean(1, keepdim=True),
                             raw["depth_var"]], 1)
    out = {}
    for name, colour, colour_var, image in (
            ("diffuse", log_irradiance, log_irradiance_var, irradiance),
            ("specular", log_specular, log_specular_var, log_specular)):
        guides = torch.cat([colour, albedo, normal, depth], 1)
        gx, gy = _gradients(guides)
        features = torch.cat([colour, torch.log1p(relu(colour_var.mean(1, keepdim=True))),
                              albedo, normal, depth, torch.log1p(relu(feature_var)), gx, gy], 1)
        out[name] = (_finite(features), image)
    return out


def layer_names(levels):
    """The convolutions of a branch with `levels` UNet levels, in order: (name, level), level
    0 at full resolution. 3 levels are enc1; enc2a, enc2b; bottleneck_a, bottleneck_b; dec2;
    dec1 (the names of every model exported before deeper ones existed); each level more
    adds enc<l>a/b above the bottleneck and dec<l> below it."""
    names = [("enc1", 0)]
    for level in range(1, levels - 1):
        names += [("enc%da" % (level + 1), level), ("enc%db" % (level + 1), level)]
    names += [("bottleneck_a", levels - 1), ("bottleneck_b", levels - 1)]
    names += [("dec%d" % (level + 1), level) for level in range(levels - 2, -1, -1)]
    return names


def _input_blocks(name, level, widths):
    """Where each input channel block of layer `name` comes from: a list of block widths in
    input order (a decoder reads [the level below, its own level's skip])."""
    if name == "enc1":
        return [INPUT_CHANNELS]
    if name == "kernels":
        return [widths[0]]
    if name.startswith("dec"):
        return [widths[level + 1], widths[level]]
    return [widths[level - 1] if name.endswith("a") else widths[level]]


class Branch(nn.Module):
    """One KPCN branch: a UNet of len(WIDTHS) levels (widths[l] channels at 1/2^l of the
    resolution, two 3x3 convolutions a level, one at full resolution, max-pooling down,
    nearest upsampling and concatenation up) whose 1x1 head predicts ITERATIONS softmax
    kernels of KERNEL x KERNEL per pixel, applied one after the other to the image."""

    def __init__(self, widths=WIDTHS, iterations=ITERATIONS, kernel=KERNEL):
        super().__init__()
        if len(widths) < 3:
            raise ValueError("a branch needs 3 or more UNet levels, got widths %s" % (widths,))
        self.widths, self.iterations, self.kernel = tuple(widths), iterations, kernel
        levels = len(widths)
        for name, level in layer_names(levels):
            cin = sum(_input_blocks(name, level, widths))
            setattr(self, name, nn.Conv2d(cin, widths[level], 3, padding=1))
        self.kernels = nn.Conv2d(widths[0], iterations * kernel * kernel, 1)
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.xavier_uniform_(m.weight)  # §5.2
                nn.init.zeros_(m.bias)
        nn.init.normal_(self.kernels.weight, std=1e-3)  # start near the box filter

    def forward(self, features, image):
        up = lambda t: F.interpolate(t, scale_factor=2, mode="nearest")  # noqa: E731
        conv = lambda name, t: F.relu(getattr(self, name)(t))  # noqa: E731
        levels = len(self.widths)
        skips = [conv("enc1", features)]
        for level in range(1, levels - 1):
            t = conv("enc%da" % (level + 1), F.max_pool2d(skips[-1], 2))
            skips.append(conv("enc%db" % (level + 1), t))
        d = conv("bottleneck_b", conv("bottleneck_a", F.max_pool2d(skips[-1], 2)))
        for level in range(levels - 2, -1, -1):
            d = conv("dec%d" % (level + 1), torch.cat([up(d), skips[level]], 1))
        logits = self.kernels(d)
        taps = self.kernel * self.kernel
        for i in range(self.iterations):
            image = apply_kernel(logits[:, i * taps:(i + 1) * taps], image, self.kernel)
        return image


def widths_of(state_dict, prefix="diffuse."):
    """The UNet widths of a state dict (exported model or run), from its tensors' shapes."""
    names = ["enc1"]
    while prefix + "enc%da.weight" % (len(names) + 1) in state_dict:
        names.append("enc%da" % (len(names) + 1))
    names.append("bottleneck_a")
    return tuple(int(state_dict[prefix + name + ".weight"].shape[0]) for name in names)


def deepen(state_dict, widths):
    """A state dict of len(widths) levels from one of fewer, computing the same function:
    the old bottleneck becomes the encoder of its level, the new decoders pass that level's
    skip through unchanged (identity on its channels, zero on the level below's), the new
    levels start from random weights. widths must extend the old widths."""
    old = widths_of(state_dict)
    if tuple(widths[:len(old)]) != old or len(widths) <= len(old):
        raise ValueError("cannot deepen widths %s to %s" % (old, tuple(widths)))
    fresh = KPCN(widths).state_dict()
    out = dict(fresh)
    rename = {"bottleneck_a": "enc%da" % len(old), "bottleneck_b": "enc%db" % len(old)}
    for key, value in state_dict.items():
        branch, name, kind = key.split(".")
        out["%s.%s.%s" % (branch, rename.get(name, name), kind)] = value
    for branch in ("diffuse", "specular"):
        for level in range(len(old) - 1, len(widths) - 1):
            w = torch.zeros_like(fresh["%s.dec%d.weight" % (branch, level + 1)])
            below = widths[level + 1]
            for c in range(widths[level]):
                w[c, below + c, 1, 1] = 1.0
            out["%s.dec%d.weight" % (branch, level + 1)] = w
            out["%s.dec%d.bias" % (branch, level + 1)] = torch.zeros(widths[level])
    return out


def widen(state_dict, widths):
    """A state dict of the same depth with wider levels (each width at least the old one),
    computing the same function: every old weight keeps its place, a new channel's input
    weights are fresh (random), and every weight that reads a new channel is zero, so the new
    channels change nothing until training moves those weights off zero."""
    old = widths_of(state_dict)
    if len(widths) != len(old) or any(w < o for w, o in zip(widths, old)):
        raise ValueError("cannot widen widths %s to %s" % (old, tuple(widths)))
    out = dict(KPCN(widths).state_dict())
    layers = layer_names(len(widths)) + [("kernels", 0)]
    for branch in ("diffuse", "specular"):
        for name, level in layers:
            key = "%s.%s." % (branch, name)
            w_old, b_old = state_dict[key + "weight"], state_dict[key + "bias"]
            w = out[key + "weight"].clone()
            cout = w_old.shape[0]
            w[:cout] = 0  # old outputs read nothing new ...
            src = dst = 0
            for o_block, n_block in zip(_input_blocks(name, level, old), _input_blocks(name, level, widths)):
                w[:cout, dst:dst + o_block] = w_old[:, src:src + o_block]  # ... but what they read
                src, dst = src + o_block, dst + n_block
            b = torch.zeros_like(out[key + "bias"])
            b[:cout] = b_old
            out[key + "weight"], out[key + "bias"] = w, b
    return out


def grow(state_dict, widths):
    """deepen, then widen: a state dict of `widths` from one of fewer or narrower levels,
    computing the same function."""
    old = widths_of(state_dict)
    if len(widths) > len(old):
        state_dict = deepen(state_dict, tuple(old) + tuple(widths[len(old):]))
    if tuple(widths_of(state_dict)) != tuple(widths):
        state_dict = widen(state_dict, widths)
    return state_dict


class KPCN(nn.Module):
    def __init__(self, widths=WIDTHS):
        super().__init__()
        self.diffuse = Branch(widths)
        self.specular = Branch(widths)

    def forward(self, raw):
        """Returns the denoised (diffuse, specular, colour); the input sizes must be
        multiples of alignment(widths)."""
        inputs = branch_inputs(raw)
        if torch.count_nonzero(raw["diffuse"]) == 0:
            # No split anywhere in the batch (model b's training): the diffuse branch would
            # filter zeros into zeros; skipping it is exact and halves the step.
            irradiance = torch.zeros_like(inputs["diffuse"][1])
        else:
            irradiance = self.diffuse(*inputs["diffuse"])
        log_specular = self.specular(*inputs["specular"])
        diffuse = (torch.relu(raw["demod"]) + ALBEDO_EPSILON) * irradiance  # eq. 4
        specular = torch.expm1(log_specular)
        return diffuse, specular, diffuse + specular


def flops_per_pixel(widths=WIDTHS, iterations=ITERATIONS, kernel=KERNEL):
    """Multiply-adds x 2 of one branch per full-resolution pixel."""
    macs = widths[0] * iterations * kernel * kernel + iterations * kernel * kernel * 3
    for name, level in layer_names(len(widths)):
        macs += widths[level] * sum(_input_blocks(name, level, widths)) * 9 / 4 ** level
    return 2 * macs


def alignment(widths):
    """What the input sizes must be multiples of: 2 to the number of poolings."""
    return 2 ** (len(widths) - 1)


def denoise(net, raw):
    """The whole op on one image, as lib/src/cnn computes it: raw planes [C, H, W] of any
    size (depth unscaled) -> denoised colour [3, H, W]. The inputs are computed at the image's
    size, then extended to a multiple of alignment() by repeating the last row and column
    (nn::run_tiled), and the outputs cropped back."""
    raw = dict(raw)
    raw["depth"], raw["depth_var"] = scale_depth(raw["depth"], raw["depth_var"])
    batch = {k: v[None] for k, v in raw.items()}
    h, w = raw["color"].shape[1:]
    a = alignment(net.diffuse.widths)
    pad = (0, (-w) % a, 0, (-h) % a)
    inputs = branch_inputs(batch)
    out = {}
    with torch.no_grad():
        for name, branch in (("diffuse", net.diffuse), ("specular", net.specular)):
            features, image = (F.pad(t, pad, mode="replicate") for t in inputs[name])
            out[name] = branch(features, image)[..., :h, :w]
        diffuse = (torch.relu(batch["demod"]) + ALBEDO_EPSILON) * out["diffuse"]
        colour = diffuse + torch.expm1(out["specular"])
    return colour[0]
