// Skipping what a frame does not need (each stage's Options has a SkipOptions `skip`):
//
//   converged tiles  A tile of kConvergedTileSize² pixels is converged where, at every pixel
//                    and colour channel, the render's relative variance
//                        Var[mean] / (colour² + 0.01)
//                    (relMSE's denominator: the pixel's expected relMSE as rendered),
//                    averaged over the pixel's 3×3 neighbourhood within its tile, is at most
//                    max_relative_error², and the pixel's own at most
//                    (kOutlierFactor · max_relative_error)². The neighbourhood makes the
//                    test one of the render's noise, not of its variance estimate's: from K
//                    seeds that estimate has K − 1 degrees of freedom, so in a tile of 1024
//                    pixels some exceed any bound set per pixel even where the render is
//                    converged, and one such pixel would hold its tile back; a 3×3 mean has
//                    9(K − 1). The cap keeps a firefly's tile denoised. Ops
//                    pass converged tiles through untouched and spend no work on them:
//                    nfor (regressions, feature prefilter, MSE/selection maps), prefilter,
//                    cnn (network tiles whose output lies in converged tiles), sure (no
//                    probes there: the result is the render, so SURE = σ²f'(x) = σ² there,
//                    exactly, and ‖y − x‖² = 0), mix (tiles with y = x: z = x, α' = 0,
//                    the network not run).
//   constant AOVs    nfor and prefilter drop a feature channel whose mean and halves hold
//                    one value over the whole frame (a flat albedo, the depth of a
//                    backdrop): nothing to filter, and a zero column of the regression.
//   zero α'          mix gives α' = 0 and runs no network where y = x on a whole tile,
//                    nor its model and t-test on a band where that holds on every tile.
//   empty extras     an extra AOV that is 0 over the frame in its mean and halves (an empty
//                    light group) is not filtered: it stays 0, what a filter gives it.
//
// The pass-through keeps the render's own error (per pixel at most max_relative_error² of
// relMSE), where a denoiser might still reduce it: lower the threshold for more accuracy, raise it
// for more speed.
//
// Pixels near converged tiles lose the converged neighbours' contribution to their
// filters (nfor's windows reach ~50 px through its passes, the CNN's its receptive field);
// tests/skip bounds the change. With `enabled` = false the ops are exactly the unskipped
// filters.
#pragma once

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"

namespace mcdn {

/// Side of the tiles of the converged map: the NL-means and regression tile (32 px), so a
/// converged tile is a unit of their work.
constexpr int kConvergedTileSize = 32;

/// A converged tile's pixel may have a relative standard error up to this multiple of
/// max_relative_error on its own (its neighbourhood's mean still within it): far beyond
/// what the variance estimate's own scatter gives a converged pixel, well within a firefly.
constexpr float kOutlierFactor = 3.0f;

struct SkipOptions {
    /// All skipping of the stage (converged tiles, constant AOVs, zero-α' tiles).
    bool enabled = true;
    /// Largest relative standard error of a converged tile's pixels and channels (over each
    /// pixel's 3×3 neighbourhood; kOutlierFactor times that for a pixel alone). 0.02: where a
    /// render is that clean, denoising it changes its error by about 1% (Cycles frames of
    /// docs/skipping.md: adaptive sampling at threshold 0.01, the best chain's relMSE +1%
    /// skipping against not; at 0.03 +41% on one of them); sky and backdrops pass. Raise it
    /// to trade accuracy for speed.
    float max_relative_error = 0.02f;
};

/// How many of a frame's tiles are converged at `skip`'s threshold (what every stage of a
/// chain on src passes through): 0 of `tiles` without a colour variance or with skip off.
struct ConvergedCount {
    int converged = 0, tiles = 0;
};
ConvergedCount count_converged_tiles(const OIIO::ImageBuf& src, const AovSet& aovs,
                                     const SkipOptions& skip = {});

}  // namespace mcdn
