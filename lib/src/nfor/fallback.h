// The safety net (issue 22): tiles where NFOR's own error estimate says its result is worse
// than the render are the render.
//
// The render's expected squared error at a pixel is its variance of the mean; §5.3's MSE
// estimate, blended with the selection map, is the filter's. Summed over a tile of
// kConvergedTileSize² pixels and the three channels, each term weighted by relMSE's
// 1 / (ŷ² + 0.01) (ŷ the blended first-pass result, smooth, the same weight on both sides),
// the filter is worse there when its sum is above the render's. A tile of 1024 pixels makes
// the sums steady where one pixel's estimate is noise (the two-buffer estimate scatters about
// as much as the squared noise it measures).
#pragma once

#include "core/planar.h"
#include "skip/converged_tiles.h"

namespace mcdn {

/// The tiles (kConvergedTileSize, like the converged map) where Σ w·mse > Σ w·variance, among
/// those not converged. `result` is ŷ. Empty map: none is.
ConvergedTiles tiles_worse_than_render(const Plane mse[3], const Plane variance[3],
                                       const Plane result[3], const ConvergedTiles& converged);

/// The map goes on nfor's output as kDenoiserTilesAttribute (core/attributes.h), which its
/// probes reuse. Int attribute on nfor's output: how many tiles fell back (of its band, in a
/// banded run).
constexpr const char* kFallbackCountAttribute = "mcdn:nfor_fallback_count";

}  // namespace mcdn
