// PD eq. 9: alpha = (sigma^2 - sigma^2 E[f'(x)]) / ||y - x||^2. Each term is far too noisy
// per pixel (PD Fig. 3), so each is averaged over a box before the ratio.
#include <algorithm>

#include "mix/mix_steps.h"
#include "ops/window_sums.h"

namespace mcdn {

Plane box_mean(const Plane& in, int radius)
{
    return separable_window_sum(in, std::vector<double>(size_t(2 * radius + 1), 1.0), radius, true);
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
