"""PyTorch versions of the mcdenoise inference ops whose semantics are ours (the others are
plain torch): train with these and the C++ engine (lib/src/nn) computes the same thing."""
import torch
import torch.nn.functional as F


def apply_kernel(logits, image, kernel):
    """KPCN eq. 9: per-pixel softmax over the k*k logits, applied to the k*k neighbourhood of
    `image` (N,C,H,W), the same weights for every channel. Logit channel t = dy*k + dx is the
    tap at offset (dy - k//2, dx - k//2); outside the image the edge pixel repeats."""
    n, c, h, w = image.shape
    pad = kernel // 2
    weights = torch.softmax(logits, dim=1)                              # N, k*k, H, W
    padded = F.pad(image, (pad, pad, pad, pad), mode="replicate")
    patches = F.unfold(padded, kernel).view(n, c, kernel * kernel, h, w)  # c major, then taps
    return (patches * weights.unsqueeze(1)).sum(dim=2)
