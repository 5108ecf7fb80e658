// Bandwidth selection by the two-buffer MSE estimate (NFOR §5.3).
#pragma once

#include <vector>

#include "core/planar.h"

namespace mcdn {

/// The two-buffer MSE estimate of one candidate (3 planes): with Â fitted to half A (using
/// B's features and weights) and B̂ to half B,
///   mse = ((B - Â)² - 2 Var + (A - B̂)² - 2 Var) / 2 - (B̂ - Â)² / 4,
/// Var the variance of the mean (a half has 2 Var); (B - Â)² - 2 Var is unbiased for the
/// MSE of Â because the noise of B is independent of Â.
std::vector<Plane> estimate_mse(const Plane* const half_a[3], const Plane* const half_b[3],
                                const Plane* const variance[3], const std::vector<Plane>& fit_a,
                                const std::vector<Plane>& fit_b);

/// The one-buffer estimate (PD §2.3, Stein's unbiased risk estimate) of one candidate f
/// for a render x with the variance of its mean Var and no halves: with f_p the fit of the
/// probed render x + eps b (b = sqrt(Var) n, n standard normal per pixel and channel),
///   mse = (f - x)² + 2 b (f_p - f) / eps - Var,
/// the middle term Monte-Carlo's estimate of 2 Var ∂f/∂x (unbiased for eps -> 0).
std::vector<Plane> sure_mse(const Plane* const render[3], const Plane* const variance[3],
                            const Plane probe[3], double eps, const std::vector<Plane>& fit,
                            const std::vector<Plane>& probed_fit);

/// Per channel 0 where the first candidate's (filtered) MSE is lower, else 1.
std::vector<Plane> select_candidate(const std::vector<Plane>& mse0, const std::vector<Plane>& mse1);

}  // namespace mcdn
