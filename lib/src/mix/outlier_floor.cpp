// A lower bound on the mix model's alpha where the render pixel is an outlier of its own
// variance: there alpha >= the pixel's own PD eq. 9,
//   alpha_9 = (sigma^2 - sigma^2 f'(x)) / ||y - x||^2, clipped to [0, 1],
// and where the render's standard error is larger still, alpha = 1: the render pixel is
// dropped (the t-test, applied after, still keeps a render the pixel's variance says is
// right).
//
// Why: the network sees the error estimates as arctan(v / (y^2 + 0.01)) (training/mix/
// model.py). A render firefly has a relative variance of thousands and SURE of tens or
// hundreds; both read as pi/2 to within 1%, so the network cannot tell which image is wrong
// and may keep the firefly (alpha ~ 0). The analytic model (eq. 9 on 21x21 box averages)
// misses it too: the firefly's sigma^2 and ||y - x||^2 are averaged with 440 neighbours
// whose eq. 9 may be small. Both models get this floor. Eq. 9 itself is too noisy to use
// everywhere (PD Fig. 3), but where the render's expected error sigma^2 dwarfs the pixel's
// value, sigma^2 dominates both its numerator and ||y - x||^2 (the firefly is what makes
// both large), and the ratio is reliable. It only ever raises alpha toward the denoised
// image, and only as far as eq. 9 says: a real bright feature the denoiser blurred has
// ||y - x||^2 >> sigma^2 and keeps the network's alpha. As samples grow, sigma^2 -> 0 and
// the rule switches itself off; the t-test (applied after it) still bounds the result.
//
// Thresholds, on the relative variance v / (y^2 + 0.01) (MixOptions: outlier, drop):
// - eq. 9 from 0.3: the render's standard error above about half the pixel's scale;
// - alpha = 1 from 1.5: the standard error above about 1.2x the scale, where the pixel's
//   value says little about its mean and eq. 9 fails too (its terms are dominated by a few
//   samples, and the one-probe sigma^2 f'(x) is noise).
// A bright feature the render does resolve (||y - x||^2 many times sigma^2) is the t-test's
// case: with alpha = 1 its t is ||y - x|| / sigma (the pixel is its own highest-variance
// neighbour M_p), and alpha' falls back toward 0 (tests/mix). The pixels and benchmark
// counts these thresholds were chosen on: docs/accuracy.md.

#include <algorithm>
#include <cmath>

#include "mcdn/metrics.h"
#include "mix/mix_steps.h"

namespace mcdn {

void outlier_floor(Plane& alpha, const Plane& variance, const Plane& y, const Plane& divergence,
                   const Plane& residual, float relative_variance, float drop_relative_variance)
{
    for (size_t i = 0; i < alpha.size(); ++i) {
        const double v = variance.px[i], scale = double(y.px[i]) * y.px[i] + kRelMseOffset;
        if (drop_relative_variance > 0 && v > drop_relative_variance * scale) {
            alpha.px[i] = 1;
            continue;
        }
        if (!(relative_variance > 0 && v > relative_variance * scale) || !(residual.px[i] > 0))
            continue;
        const double eq9 = (v - divergence.px[i]) / residual.px[i];
        if (!std::isfinite(eq9))
            continue;
        alpha.px[i] = std::max(alpha.px[i], float(std::clamp(eq9, 0.0, 1.0)));
    }
}

}  // namespace mcdn
