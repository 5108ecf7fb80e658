#!/usr/bin/python3
"""Makes the PyTorch-vs-C++ fixture of the inference engine (tests/nn/pytorch_test.cpp):
a small random network that uses every op of lib/src/nn, its weights file, an input and
PyTorch's outputs.

    /usr/bin/python3 training/common/make_nn_fixture.py [tests/data/nn]

writes tiny_net.mcdnw (the weights) and tiny_net_io.mcdnw (tensors "input.features",
"output.denoised", "output.decoder", each NHWC [H, W, C], in the same file format).
The C++ test builds the same graph with the Net builder; keep the two in step.
"""
import os
import sys

import numpy as np
import torch
import torch.nn as nn
import torch.nn.functional as F

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from nn_ops import apply_kernel  # noqa: E402
from weights import write_weights  # noqa: E402

HEIGHT, WIDTH, FEATURES, KERNEL = 24, 32, 6, 5


class TinyNet(nn.Module):
    """A UNet-ish kernel predictor in miniature: conv+ReLU (3x3 and 5x5), a residual block,
    two max-pools, two nearest upsamplings with concat skips, a 5x5 softmax kernel applied
    to the first three input channels (the noisy colour)."""

    def __init__(self):
        super().__init__()
        self.enc1 = nn.Conv2d(FEATURES, 16, 5, padding=2)
        self.enc1b = nn.Conv2d(16, 16, 3, padding=1)
        self.enc2 = nn.Conv2d(16, 24, 3, padding=1)
        self.res_conv1 = nn.Conv2d(24, 24, 3, padding=1)
        self.res_conv2 = nn.Conv2d(24, 24, 3, padding=1)
        self.bottleneck = nn.Conv2d(24, 32, 3, padding=1)
        self.dec2 = nn.Conv2d(32 + 24, 24, 3, padding=1)
        self.dec1 = nn.Conv2d(24 + 16, 16, 3, padding=1)
        self.kernel = nn.Conv2d(16, KERNEL * KERNEL, 3, padding=1)

    def forward(self, x):
        e1 = F.relu(self.enc1b(F.relu(self.enc1(x))))
        e2 = F.relu(self.enc2(F.max_pool2d(e1, 2)))
        r = self.res_conv2(F.relu(self.res_conv1(e2)))
        e2 = F.relu(e2 + r)
        b = F.relu(self.bottleneck(F.max_pool2d(e2, 2)))
        d2 = F.relu(self.dec2(torch.cat([F.interpolate(b, scale_factor=2, mode="nearest"), e2], 1)))
        d1 = F.relu(self.dec1(torch.cat([F.interpolate(d2, scale_factor=2, mode="nearest"), e1], 1)))
        logits = self.kernel(d1)
        return apply_kernel(logits, x[:, 0:3], KERNEL), d1


def nhwc(t):
    return t[0].permute(1, 2, 0).contiguous()


def main():
    out_dir = sys.argv[1] if len(sys.argv) > 1 else os.path.join(
        os.path.dirname(os.path.abspath(__file__)), "..", "..", "tests", "data", "nn")
    torch.manual_seed(6)
    net = TinyNet().eval()
    with torch.no_grad():
        net.kernel.weight.mul_(4.0)  # sharper softmax kernels than the default init gives
        for p in net.parameters():
            if p.dim() == 1:
                p.uniform_(-0.2, 0.2)
    x = torch.rand(1, FEATURES, HEIGHT, WIDTH)
    x[:, 0:3] *= 4.0  # HDR-ish colour
    with torch.no_grad():
        denoised, decoder = net(x)
        denoised64, _ = net.double()(x.double())
    print("float32 vs float64 PyTorch, max abs difference: %.3g" % (denoised.double() - denoised64).abs().max())

    # state_dict keys "res_conv1.weight" -> the C++ names "res.conv1.weight".
    state = {k.replace("res_", "res."): v for k, v in net.float().state_dict().items()}
    metadata = {"network": "tiny_net", "purpose": "PyTorch equivalence fixture of lib/src/nn",
                "features": FEATURES, "kernel": KERNEL, "torch": torch.__version__, "seed": 6}
    write_weights(os.path.join(out_dir, "tiny_net.mcdnw"), state, metadata)
    write_weights(os.path.join(out_dir, "tiny_net_io.mcdnw"),
                  {"input.features": nhwc(x), "output.denoised": nhwc(denoised),
                   "output.decoder": nhwc(decoder)},
                  {"height": HEIGHT, "width": WIDTH, "layout": "NHWC"})
    print("wrote", os.path.normpath(out_dir))


if __name__ == "__main__":
    main()
