// PD eq. 9: alpha = (sigma^2 - sigma^2 E[f'(x)]) / ||y - x||^2. Each term is far too noisy
// per pixel (PD Fig. 3), so each is averaged over a box before the ratio.
#include <algorithm>

#include "mix/mix_steps.h"

namespace mcdn {

Plane box_mean(const Plane& in, int radius)
{
    const int w = in.width, h = in.height;
    Plane rows(w, h), out(w, h);
    for (int y = 0; y < h; ++y) {
        const float* src = in.row(y);
        for (int x = 0; x < w; ++x) {
            int x0 = std::max(0, x - radius), x1 = std::min(w - 1, x + radius);
            double s = 0;
            for (int i = x0; i <= x1; ++i)
                s += src[i];
            rows(x, y) = float(s / (x1 - x0 + 1));
        }
    }
    for (int y = 0; y < h; ++y) {
        int y0 = std::max(0, y - radius), y1 = std::min(h - 1, y + radius);
        for (int x = 0; x < w; ++x) {
            double s = 0;
            for (int j = y0; j <= y1; ++j)
                s += rows(x, j);
            out(x, y) = float(s / (y1 - y0 + 1));
        }
    }
    return out;
}

void analytic_alpha(Plane alpha[3], const MixInputs& in, int radius)
{
    for (int c = 0; c < 3; ++c) {
        Plane variance = box_mean(in.variance[c], radius);
        Plane divergence = box_mean(in.divergence[c], radius);
        Plane residual = box_mean(in.residual[c], radius);
        alpha[c] = Plane(variance.width, variance.height);
        for (size_t i = 0; i < variance.size(); ++i) {
            double numerator = double(variance.px[i]) - divergence.px[i];
            double denominator = residual.px[i];
            // y == x (nothing to mix) or a numerator <= 0 (the denoiser adds error): keep x.
            double a = denominator > 0 ? numerator / denominator : 0.0;
            alpha[c].px[i] = float(std::clamp(a, 0.0, 1.0));
        }
    }
}

}  // namespace mcdn
