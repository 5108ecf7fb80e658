// The safety net of the denoising stages (issue 22): tiles where a stage's own estimate of
// its error says its result is worse than the render are the render. nfor decides on its
// §5.3 MSE estimate, sure (for any denoiser, the CNN's among them) on SURE.
//
// The render's expected squared error at a pixel is its variance of the mean; the stage's
// estimate of its own, per pixel, is the other side. Each is taken as computed per pixel,
// before any smoothing: a filter over the estimate (NFOR's §5.3 map filter) spreads one
// pixel's estimate over its window, so that one pixel of garbage (1e30, a NaN's repair) would
// decide every tile within reach. Over a tile of kConvergedTileSize² pixels and the three
// channels, each pixel's difference estimate − variance weighted by relMSE's 1 / (ŷ² + 0.01)
// (ŷ the stage's result), the result is worse when the trimmed sum of the differences is
// above 0: the kFallbackTrim largest and smallest dropped, so that a few pixels (garbage, a
// heavy-tailed sample, a probe's noise) do not decide the tile, while a blotch, which covers
// many of its pixels, does. A per-pixel estimate scatters about as much as the squared noise
// it measures; over 3072 terms the sum is steady.
#pragma once

#include <vector>

#include "core/planar.h"
#include "skip/converged_tiles.h"

namespace mcdn {

/// The share of a tile's terms dropped at each end before they are summed.
constexpr double kFallbackTrim = 0.05;

/// The tiles (kConvergedTileSize, like the converged map) where the trimmed sum of
/// w·(mse − variance) is above 0, among those not in `skipped` (converged, or passed
/// through). `result` is ŷ, `mse` the per-pixel estimate. Empty map: none.
ConvergedTiles tiles_worse_than_render(const Plane mse[3], const Plane variance[3],
                                       const Plane result[3], const ConvergedTiles& skipped);

/// The sum of `terms` without the kFallbackTrim share of them at each end (sorts them).
double trimmed_sum(std::vector<double>& terms);

}  // namespace mcdn
