// A lower bound on the network's alpha where the render pixel is an outlier of its own
// variance: there alpha >= the pixel's own PD eq. 9,
//   alpha_9 = (sigma^2 - sigma^2 f'(x)) / ||y - x||^2, clipped to [0, 1].
//
// Why: the network sees the error estimates as arctan(v / (y^2 + 0.01)) (training/mix/
// model.py). A render firefly has a relative variance of thousands and SURE of tens or
// hundreds; both read as pi/2 to within 1%, so the network cannot tell which image is wrong
// and may keep the firefly (alpha ~ 0: small/0001_exterior at 16 spp kept one pixel at 47
// over a reference of 0.12, relMSE 10.4 against NFOR's 0.12). Eq. 9 itself is too noisy to use
// everywhere (PD Fig. 3), but where the render's expected error sigma^2 dwarfs the pixel's
// value, sigma^2 dominates both its numerator and ||y - x||^2 (the firefly is what makes
// both large), and the ratio is reliable. It only ever raises alpha toward the denoised
// image, and only as far as eq. 9 says: a real bright feature the denoiser blurred has
// ||y - x||^2 >> sigma^2 and keeps the network's alpha. As samples grow, sigma^2 -> 0 and
// the rule switches itself off; the t-test (applied after it) still bounds the result.
#include <algorithm>
#include <cmath>

#include "mix/mix_steps.h"

namespace mcdn {

namespace {
// The offset of the relMSE denominator y^2 + 0.01, as in the network's inputs (net_alpha.cpp).
constexpr double kRelativeErrorOffset = 0.01;
}  // namespace

void outlier_floor(Plane& alpha, const Plane& variance, const Plane& y, const Plane& divergence,
                   const Plane& residual, float relative_variance)
{
    for (size_t i = 0; i < alpha.size(); ++i) {
        const double v = variance.px[i], yi = y.px[i];
        if (!(v > relative_variance * (yi * yi + kRelativeErrorOffset)) || !(residual.px[i] > 0))
            continue;
        const double eq9 = (v - divergence.px[i]) / residual.px[i];
        if (!std::isfinite(eq9))
            continue;
        alpha.px[i] = std::max(alpha.px[i], float(std::clamp(eq9, 0.0, 1.0)));
    }
}

}  // namespace mcdn
