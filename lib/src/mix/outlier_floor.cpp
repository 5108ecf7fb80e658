// A lower bound on the network's alpha where the render pixel is an outlier of its own
// variance: there alpha >= the pixel's own PD eq. 9,
//   alpha_9 = (sigma^2 - sigma^2 f'(x)) / ||y - x||^2, clipped to [0, 1],
// and where the render's standard error is larger still, alpha = 1: the render pixel is
// dropped (the t-test, applied after, still keeps a render the pixel's variance says is
// right).
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
//
// Thresholds, on the relative variance v / (y^2 + 0.01) (bench_mix over 53 inputs: box,
// the Tungsten pair and 48 levels of the 12 held-out generated crops; within 2 % of the
// better input: 46 at 10 / none, 47 at 0.3 / none, 49 at 0.3 / 3; flat for eq. 9 from 0.1
// to 0.3 and for the drop from 1 to 3 with that network. With one network per denoiser
// (models/README.md) all 53 with NFOR at drop 1-3, with the KPCN op 53 at 1-1.5 and 52 at
// 2-3; nothing else moved, the biased blur and 10 training crops included):
// - eq. 9 from 0.3 (the render's standard error above half the pixel's scale). At 10 the
//   network kept render pixels with standard errors of 0.7-2x their scale that eq. 9 gives
//   to the denoiser (0046_exterior 16 spp: x = 9.1, y = 5.9, reference 1.7, sigma^2 = 19,
//   alpha_9 = 1, network 0).
// - alpha = 1 from 1.5 (standard error above 1.2x the scale: the pixel's value says little
//   about its mean). Eq. 9 fails there: its terms are dominated by a few samples, and the
//   one-probe sigma^2 f'(x) is noise. 0016_fine at 4 spp with the KPCN op: a blob of render
//   pixels at 2.6 over a reference of 0.31, sigma^2 = 0.42 (1.6x the scale; four samples
//   underestimate it), alpha_9 = 0.09 kept them: +2.3 % RMSE over the CNN alone.
//   0040_metal 256 spp: x = 98 over a reference of 0.22, y = 9.0, sigma^2 = 9583,
//   ||y - x||^2 = 7942, sigma^2 f'(x) = 31030 (f' = 3.2, which no smoothing denoiser has):
//   alpha_9 < 0 kept the firefly. Eq. 9 without the divergence
//   term (sigma^2 / ||y - x||^2) is not enough either: the light of training crop 0005_glass
//   at 4 spp, x = 82000 over a reference of 13200, y = 8240, has ||y - x||^2 = 2.8 sigma^2
//   (four samples underestimate a heavy tail's variance): 0.36, and RMSE 2.3x NFOR's.
//   A bright feature the render does resolve (||y - x||^2 many times sigma^2) is the
//   t-test's case: with alpha = 1 its t is ||y - x|| / sigma (the pixel is its own
//   highest-variance neighbour M_p), and alpha' falls back toward 0 (tests/mix).

#include <algorithm>
#include <cmath>

#include "mix/mix_steps.h"

namespace mcdn {

namespace {
// The offset of the relMSE denominator y^2 + 0.01, as in the network's inputs (net_alpha.cpp).
constexpr double kRelativeErrorOffset = 0.01;
}  // namespace

void outlier_floor(Plane& alpha, const Plane& variance, const Plane& y, const Plane& divergence,
                   const Plane& residual, float relative_variance, float drop_relative_variance)
{
    for (size_t i = 0; i < alpha.size(); ++i) {
        const double v = variance.px[i], scale = double(y.px[i]) * y.px[i] + kRelativeErrorOffset;
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
