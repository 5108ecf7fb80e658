// The steps of the progressive mix (PD §4), one file each: the analytic alpha (eq. 9),
// the network's alpha (§4.3), and the t-test bound (eq. 12-18).
#pragma once

#include "core/planar.h"
#include "mcdn/mix.h"

namespace mcdn {

/// What the mix reads, one plane per colour channel.
struct MixInputs {
    Plane x[3], y[3], variance[3], sure[3], divergence[3], residual[3];
};

/// Eq. 9 with box-averaged terms, clipped to [0, 1].
void analytic_alpha(Plane alpha[3], const MixInputs& in, int radius);

/// sigma_s of eq. 15: min(sqrt(spatial variance of x), 1) * scale.
float t_test_sigma(const MixInputs& in, float scale);

/// Eq. 12-18: scales alpha by 1 - S(a(|t| - c)) in place.
void t_test_bound(Plane& alpha, const Plane& x, const Plane& y, const Plane& variance,
                  float sigma_s, const MixOptions& options);

/// Mean over a (2r+1)^2 box clipped to the image (separable, in double).
Plane box_mean(const Plane& in, int radius);

}  // namespace mcdn
