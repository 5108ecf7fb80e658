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
WIDTHS = (16, 32, 48)     # UNet widths at full, 1/2 and 1/4 resolution


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


class Branch(nn.Module):
    """One KPCN branch: a 3-level UNet (WIDTHS) whose 1x1 head predicts ITERATIONS softmax
    kernels of KERNEL x KERNEL per pixel, applied one after the other to the image."""

    def __init__(self, widths=WIDTHS, iterations=ITERATIONS, kernel=KERNEL):
        super().__init__()
        w1, w2, w3 = widths
        self.iterations, self.kernel = iterations, kernel
        self.enc1 = nn.Conv2d(INPUT_CHANNELS, w1, 3, padding=1)
        self.enc2a = nn.Conv2d(w1, w2, 3, padding=1)
        self.enc2b = nn.Conv2d(w2, w2, 3, padding=1)
        self.bottleneck_a = nn.Conv2d(w2, w3, 3, padding=1)
        self.bottleneck_b = nn.Conv2d(w3, w3, 3, padding=1)
        self.dec2 = nn.Conv2d(w3 + w2, w2, 3, padding=1)
        self.dec1 = nn.Conv2d(w2 + w1, w1, 3, padding=1)
        self.kernels = nn.Conv2d(w1, iterations * kernel * kernel, 1)
        for m in self.modules():
            if isinstance(m, nn.Conv2d):
                nn.init.xavier_uniform_(m.weight)  # §5.2
                nn.init.zeros_(m.bias)
        nn.init.normal_(self.kernels.weight, std=1e-3)  # start near the box filter

    def forward(self, features, image):
        up = lambda t: F.interpolate(t, scale_factor=2, mode="nearest")  # noqa: E731
        e1 = F.relu(self.enc1(features))
        e2 = F.relu(self.enc2b(F.relu(self.enc2a(F.max_pool2d(e1, 2)))))
        b = F.relu(self.bottleneck_b(F.relu(self.bottleneck_a(F.max_pool2d(e2, 2)))))
        d2 = F.relu(self.dec2(torch.cat([up(b), e2], 1)))
        d1 = F.relu(self.dec1(torch.cat([up(d2), e1], 1)))
        logits = self.kernels(d1)
        taps = self.kernel * self.kernel
        for i in range(self.iterations):
            image = apply_kernel(logits[:, i * taps:(i + 1) * taps], image, self.kernel)
        return image


class KPCN(nn.Module):
    def __init__(self, widths=WIDTHS):
        super().__init__()
        self.diffuse = Branch(widths)
        self.specular = Branch(widths)

    def forward(self, raw):
        """Returns the denoised (diffuse, specular, colour); the input sizes must be
        multiples of 4 (two poolings)."""
        inputs = branch_inputs(raw)
        irradiance = self.diffuse(*inputs["diffuse"])
        log_specular = self.specular(*inputs["specular"])
        diffuse = (torch.relu(raw["demod"]) + ALBEDO_EPSILON) * irradiance  # eq. 4
        specular = torch.expm1(log_specular)
        return diffuse, specular, diffuse + specular


def flops_per_pixel(widths=WIDTHS, iterations=ITERATIONS, kernel=KERNEL):
    """Multiply-adds x 2 of one branch per full-resolution pixel."""
    w1, w2, w3 = widths
    full = INPUT_CHANNELS * w1 * 9 + (w2 + w1) * w1 * 9 + w1 * iterations * kernel * kernel
    half = w1 * w2 * 9 + w2 * w2 * 9 + (w3 + w2) * w2 * 9
    quarter = w2 * w3 * 9 + w3 * w3 * 9
    apply = iterations * kernel * kernel * 3
    return 2 * (full + half / 4 + quarter / 16 + apply)


def denoise(net, raw):
    """The whole op on one image, as lib/src/cnn computes it: raw planes [C, H, W] of any
    size (depth unscaled) -> denoised colour [3, H, W]. The inputs are computed at the image's
    size, then extended to a multiple of 4 by repeating the last row and column
    (nn::run_tiled), and the outputs cropped back."""
    raw = dict(raw)
    raw["depth"], raw["depth_var"] = scale_depth(raw["depth"], raw["depth_var"])
    batch = {k: v[None] for k, v in raw.items()}
    h, w = raw["color"].shape[1:]
    pad = (0, (-w) % 4, 0, (-h) % 4)
    inputs = branch_inputs(batch)
    out = {}
    with torch.no_grad():
        for name, branch in (("diffuse", net.diffuse), ("specular", net.specular)):
            features, image = (F.pad(t, pad, mode="replicate") for t in inputs[name])
            out[name] = branch(features, image)[..., :h, :w]
        diffuse = (torch.relu(batch["demod"]) + ALBEDO_EPSILON) * out["diffuse"]
        colour = diffuse + torch.expm1(out["specular"])
    return colour[0]
