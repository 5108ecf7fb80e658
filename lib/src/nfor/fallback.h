// The safety net (issue 22): tiles where NFOR's own error estimate says its result is worse
// than the render are the render.
//
// The render's expected squared error at a pixel is its variance of the mean; §5.3's MSE
// estimate of the candidates, blended with the selection map, is the filter's — the
// estimate as computed per pixel, before §5.3's map filter: that filter spreads one pixel's
// estimate over its window, so that one pixel of garbage (1e30, a NaN's repair) would decide
// every tile within reach. Over a tile of kConvergedTileSize² pixels and the three channels,
// each pixel's difference filter − render weighted by relMSE's 1 / (ŷ² + 0.01) (ŷ the
// blended first-pass result, smooth), the filter is worse when the trimmed sum of the
// differences is above 0: the kFallbackTrim largest and smallest dropped, so that a few
// pixels (garbage, a heavy-tailed sample, a disagreement of the halves) do not decide the
// tile, while a blotch, which covers many of its pixels, does. The per-pixel estimate
// scatters about as much as the squared noise it measures; over 3072 terms its sum is steady.
#pragma once

#include <vector>

#include "core/planar.h"
#include "skip/converged_tiles.h"

namespace mcdn {

/// The share of a tile's terms dropped at each end before they are summed.
constexpr double kFallbackTrim = 0.05;

/// The tiles (kConvergedTileSize, like the converged map) where the trimmed sum of
/// w·(mse − variance) is above 0, among those not converged. `result` is ŷ. Empty map: none.
/// `mse` is the unfiltered blended estimate.
ConvergedTiles tiles_worse_than_render(const Plane mse[3], const Plane variance[3],
                                       const Plane result[3], const ConvergedTiles& converged);

/// The sum of `terms` without the kFallbackTrim share of them at each end (sorts them).
double trimmed_sum(std::vector<double>& terms);

/// The map goes on nfor's output as kDenoiserTilesAttribute (core/attributes.h), which its
/// probes reuse; the count as kNforFallbackCountAttribute (mcdn/nfor.h).

}  // namespace mcdn
