// Skipping what a frame does not need (each stage's Options has a SkipOptions `skip`):
//
//   converged tiles  A tile of kConvergedTileSize² pixels is converged where, at every pixel
//                    and colour channel, the render's relative standard error
//                        sqrt(Var[mean]) / sqrt(colour² + 0.01)
//                    is at most max_relative_error (the denominator is relMSE's, so its
//                    square is the pixel's expected relMSE as rendered). The worst pixel
//                    decides, so one noisy pixel (a firefly) keeps its tile denoised. Ops
//                    pass converged tiles through untouched and spend no work on them:
//                    nfor (regressions, feature prefilter, MSE/selection maps), prefilter,
//                    cnn (network tiles whose output lies in converged tiles), sure (no
//                    probes there: the result is the render, so SURE = σ²f'(x) = σ² there,
//                    exactly, and ‖y − x‖² = 0), mix (tiles with y = x: z = x, α' = 0,
//                    the network not run).
//   constant AOVs    nfor and prefilter drop a feature channel whose mean and halves hold
//                    one value over the whole frame (a flat albedo, the depth of a
//                    backdrop): nothing to filter, and a zero column of the regression.
//   zero α'          mix gives α' = 0 and runs no network where y = x on a whole tile.
//
// The pass-through keeps the render's own error (per pixel at most max_relative_error² of
// relMSE), where a denoiser might still reduce it: lower the threshold for more accuracy, raise it for more speed.
//
// Pixels near converged tiles lose the converged neighbours' contribution to their
// filters (nfor's windows reach ~50 px through its passes, the CNN's its receptive field);
// tests/skip bounds the change. With `enabled` = false the ops are exactly the unskipped
// filters.
#pragma once

namespace mcdn {

/// Side of the tiles of the converged map: the NL-means and regression tile (32 px), so a
/// converged tile is a unit of their work.
constexpr int kConvergedTileSize = 32;

struct SkipOptions {
    /// All skipping of the stage (converged tiles, constant AOVs, zero-α' tiles).
    bool enabled = true;
    /// Largest relative standard error of a converged tile's worst pixel and channel. 0.08:
    /// well below the worst pixel of a render still worth denoising, above that of nearly
    /// every tile of a converged reference, so only tiles of reference quality pass through.
    float max_relative_error = 0.08f;
};

}  // namespace mcdn
