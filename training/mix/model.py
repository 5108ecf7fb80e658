"""The mixing network h_NN of progressive denoising (Firmino et al. 2022, §4.3) and its input
transforms, shared by train.py, export.py and make_fixture.py. lib/src/mix/net_alpha.cpp
computes exactly the same: keep the two in step (tests/mix/net_test.cpp checks them).

Inputs, 18 channels, each an RGB triple in this order (INPUT_LAYOUT):
    0-2   HDR   x, the render                     signed_log1p(x) = sign(x) log(1 + |x|)
    3-5   DEN   y, the denoised image (NFOR)      signed_log1p(y)
    6-8   VAR   Var[x], variance of the mean      arctan(VAR  / (y^2 + 0.01))
    9-11  SURE  SURE of y                          arctan(SURE / (y^2 + 0.01))
    12-14 DIV   sigma^2 f'(x)                      arctan(DIV  / (y^2 + 0.01))
    15-17 RES   ||y - x||^2                        arctan(RES  / (y^2 + 0.01))
The paper's arctan bounds the error inputs; dividing them by y^2 + 0.01 (the relMSE
denominator, y = the denoised image of the sample, whichever slot it sits in) first makes them
relative, so the same network sees a dark and a bright region of equal relative noise alike.
All four share the divisor, so ratios such as eq. 9 stay ratios for small values.

Network: conv1 5x5 18->48 ReLU; two residual blocks res{1,2}: conv1 3x3 ReLU, conv2 3x3,
x = ReLU(x + r); out 3x3 48->9. Output channel k*3 + c is x_{k+1} of colour channel c
(x1 RGB, x2 RGB, x3 RGB). f_act = (x1 - x2) / max(x3, 1e-6) (eq. 19), clipped to [0, 1]:
the mixing parameter of slot a toward slot b, z = a + f (b - a).
"""
import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

INPUT_LAYOUT = "pd-mix-1"  # the feature layout above; the C++ loader checks this tag
INPUTS = 18
FEATURES = 48
ERROR_DENOMINATOR_OFFSET = 0.01
F_ACT_EPSILON = 1e-6


def signed_log1p(v):
    return torch.sign(v) * torch.log1p(torch.abs(v))


def features(a, b, error_a, error_b, divergence, residual, y):
    """[N, 18, H, W] network input. a/b: the two radiance slots (HDR, DEN unswapped),
    error_a/error_b: their squared-error estimates (VAR, SURE unswapped), y: the denoised
    image (normalises the error inputs; not swapped)."""
    scale = 1.0 / (y * y + ERROR_DENOMINATOR_OFFSET)
    return torch.cat([signed_log1p(a), signed_log1p(b),
                      torch.atan(error_a * scale), torch.atan(error_b * scale),
                      torch.atan(divergence * scale), torch.atan(residual * scale)], dim=1)


class ResBlock(nn.Module):
    def __init__(self, channels):
        super().__init__()
        self.conv1 = nn.Conv2d(channels, channels, 3, padding=1)
        self.conv2 = nn.Conv2d(channels, channels, 3, padding=1)

    def forward(self, x):
        return F.relu(x + self.conv2(F.relu(self.conv1(x))))


class MixNet(nn.Module):
    """h_NN: returns the raw outputs [N, 9, H, W] (x1, x2, x3 per colour channel)."""

    def __init__(self, features=FEATURES):
        super().__init__()
        self.conv1 = nn.Conv2d(INPUTS, features, 5, padding=2)
        self.res1 = ResBlock(features)
        self.res2 = ResBlock(features)
        self.out = nn.Conv2d(features, 9, 3, padding=1)
        with torch.no_grad():
            # Start at alpha = 0.5 everywhere, inside the clip range where gradients flow:
            # small output weights, x1 - x2 = 0.5, x3 = 1.
            self.out.weight.mul_(0.1)
            self.out.bias.copy_(torch.tensor([0.5] * 3 + [0.0] * 3 + [1.0] * 3))

    def forward(self, x):
        x = F.relu(self.conv1(x))
        return self.out(self.res2(self.res1(x)))


def f_act(raw, leak=0.0):
    """Eq. 19 per colour channel, clipped to [0, 1]: [N, 3, H, W].

    leak > 0 (training only) changes the gradient, never the value: where the clip or the
    max(x3, eps) is active the exact function has no gradient, so a pixel stuck at alpha = 0
    (we saw fireflies stuck there: x1 < x2) could never be corrected. There the backward pass
    uses leak * (x1 - x2) / (|x3| + 1) instead, which points the same way as the ratio."""
    x1, x2, x3 = raw[:, 0:3], raw[:, 3:6], raw[:, 6:9]
    ratio = (x1 - x2) / torch.clamp(x3, min=F_ACT_EPSILON)
    alpha = torch.clamp(ratio, 0.0, 1.0)
    if leak > 0:
        stuck = ((ratio < 0) | (ratio > 1) | (x3 < F_ACT_EPSILON)).float()
        surrogate = stuck * leak * (x1 - x2) / (torch.abs(x3) + 1.0)
        alpha = alpha + surrogate - surrogate.detach()
    return alpha


def mix(net, x, y, variance, sure, divergence, residual, swap=None, leak=0.0):
    """z and the mixing parameter. swap: bool tensor [N] (or None): where true, HDR<->DEN and
    VAR<->SURE trade places (§4.3), the network's f is beta of z = y + beta (x - y), and the
    alpha returned is 1 - beta, so z and alpha mean the same in both cases."""
    a, b, ea, eb = x, y, variance, sure
    if swap is not None:
        s = swap.view(-1, 1, 1, 1)
        a, b = torch.where(s, y, x), torch.where(s, x, y)
        ea, eb = torch.where(s, sure, variance), torch.where(s, variance, sure)
    f = f_act(net(features(a, b, ea, eb, divergence, residual, y)), leak)
    z = a + f * (b - a)
    alpha = f if swap is None else torch.where(swap.view(-1, 1, 1, 1), 1 - f, f)
    return z, alpha


def smape(z, reference):
    """SMAPE as in ../shared/data/README.md: mean |z - r| / (|z| + |r| + 0.01)."""
    return (torch.abs(z - reference) / (torch.abs(z) + torch.abs(reference) + 0.01)).mean()


def log_l1(z, reference):
    """mean |slog(z) - slog(r)|, slog = signed_log1p. Added to SMAPE in training because
    SMAPE's gradient vanishes on fireflies: d/dz of |z - r| / (|z| + |r|) is ~2r / z^2, so a
    kept render firefly of z = 50 over r = 0.1 pulls on alpha 10^4 times less than an
    ordinary pixel, while this term pulls with (y - x) / (1 + z), ~1 there and at most 1 per
    unit of y - x everywhere (it grows like log, so the references' own fireflies do not
    swamp a batch as a relMSE term would)."""
    return torch.abs(signed_log1p(z) - signed_log1p(reference)).mean()


def relmse(z, reference):
    """relMSE as in ../shared/data/README.md: mean (z - r)^2 / (r^2 + 0.01) (reporting only)."""
    return ((z - reference) ** 2 / (reference * reference + 0.01)).mean()


PLANES = ("x", "y", "variance", "sure", "divergence", "residual", "reference")


def load_sample(path):
    """{plane: float32 [3, H, W]} and spp from a prepare.py .npz; non-finite values -> 0."""
    with np.load(path) as f:
        out = {k: np.nan_to_num(f[k].astype(np.float32), nan=0.0, posinf=0.0, neginf=0.0)
               for k in PLANES}
        out["spp"] = int(f["spp"])
    return out
