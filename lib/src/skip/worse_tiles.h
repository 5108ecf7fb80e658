// The safety net of the denoising stages (issue 22): tiles where a stage's own estimate of
// its error says its result is worse than the render are the render. nfor decides on its
// §5.3 MSE estimate, sure (for any denoiser, the CNN's among them) on SURE.
//
// The render's expected squared error at a pixel is its variance of the mean; the stage's
// estimate of its own, per pixel, is the other side. The stage's is taken as computed per
// pixel, before any smoothing: a filter over the estimate (NFOR's §5.3 map filter) spreads
// one pixel's estimate over its window, so that one pixel of garbage (1e30, a NaN's repair)
// would decide every tile within reach. Over a tile of kConvergedTileSize² pixels and the
// three channels, each term weighted by relMSE's 1 / (ŷ² + 0.01) (ŷ the stage's result),
// the result is worse when the sum of the stage's estimates, without their kFallbackTrim
// share of the largest, is above the sum of the render's variances: a few pixels (garbage,
// a heavy-tailed sample, a probe's noise) do not decide the tile, while a blotch, which
// covers many of its pixels, does. The render's side is not trimmed: its largest variances
// are its real error (a firefly), and a symmetric trim of both (dropping the render's
// largest variances too) made the render look better than it is at low sample counts,
// where the variance of the mean is most skewed — every tile of the generated bump and
// metal crops at 4 spp fell back, at 2–4× NFOR's error. Dropping the filter's largest
// estimates errs toward the filter. A per-pixel estimate scatters about as much as the
// squared noise it measures; over 3072 terms the sums are steady.
#pragma once

#include <vector>

#include "core/planar.h"
#include "skip/converged_tiles.h"

namespace mcdn {

/// The share of a tile's largest estimates dropped before they are summed.
constexpr double kFallbackTrim = 0.05;

/// The tiles (kConvergedTileSize, like the converged map) where Σ w·mse without its
/// kFallbackTrim share of the largest terms is above Σ w·variance, among those not in
/// `skipped` (converged, or passed through). `result` is ŷ, `mse` the per-pixel estimate.
/// Empty map: none.
ConvergedTiles tiles_worse_than_render(const Plane mse[3], const Plane variance[3],
                                       const Plane result[3], const ConvergedTiles& skipped);

/// The sum of `terms` without the kFallbackTrim share of the largest (reorders them).
double top_trimmed_sum(std::vector<double>& terms);

}  // namespace mcdn
