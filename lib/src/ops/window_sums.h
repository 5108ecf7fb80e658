// Separable sums over a (2r+1)² window clipped to the plane, for the stages'
// neighbourhoods: the mix's (the analytic model's box means, eq. 9; the t-test's Gaussian
// sums, eq. 15) and choose's (SURE summed over a window, its weight smoothed).
#pragma once

#include <vector>

#include "core/planar.h"

namespace mcdn {

/// sum over the clipped window of taps[dx] * taps[dy] * in(q): a row pass, then a column
/// pass, each output summed in double in increasing tap order. `mean`: each pass divides by
/// its clipped tap count instead (taps are then 1: a box mean). Threaded over rows and
/// vectorised across pixels; every output is one thread's, in the same order for any
/// thread count or ISA.
Plane separable_window_sum(const Plane& in, const std::vector<double>& taps, int radius,
                           bool mean = false);

}  // namespace mcdn
