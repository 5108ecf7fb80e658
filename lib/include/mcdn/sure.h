// Monte-Carlo SURE: a per-pixel estimate of any denoiser's squared error, without a
// reference (Firmino et al. 2022, "Progressive Denoising", §2.3 eq. 1 and §3.2 eq. 2).
//
//   SURE = ||y - x||^2 + 2 tr(J_F(x) Sigma) - tr(Sigma)          per pixel and channel
//   tr(J_F Sigma) ~ 1/(eps K) sum_k b_k^T (F(x + eps b_k) - F(x)),  b_k ~ N(0, Sigma)
//
// x is the render, y = F(x) the denoised image, Sigma the per-pixel variance of the mean.
// Each probe moves the render and both half buffers by the same eps b, so x = (A + B) / 2
// stays consistent for denoisers that read the halves (NFOR). Cost: K + 1 denoiser runs.
#pragma once

#include <cstdint>
#include <functional>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/skip.h"
#include "mcdn/threads.h"

namespace mcdn {

/// A denoiser as SURE sees it: dst = src with the colour role replaced by the estimate
/// (every op of this library, and any chain of them, has this shape).
using Denoiser = std::function<bool(ImageBuf& dst, const ImageBuf& src)>;

/// The largest relative probe step SureOptions::epsilon_relative accepts: beyond it the
/// difference quotient measures the denoiser's response to a different image.
constexpr float kMaxEpsilonRelative = 0.1f;

struct SureOptions {
    AovSpec aovs;
    /// K, the number of Monte Carlo probes (PD §3.2 uses 1 or 4).
    int probes = 1;
    /// The probe step: eps is chosen so that eps times the mean standard deviation sqrt(Var)
    /// is this fraction of the mean |x| of the image (the mean, not the RMS: a heavy tail's
    /// few huge variances would set the step of every pixel). Scale-free (a 100x brighter
    /// render gets the same relative step);
    /// 1e-3 sits between float round-off in the denoiser (~1e-6 relative) and the
    /// nonlinearity of NL-means weights (tested in tests/sure).
    float epsilon_relative = 1e-3f;  // (0, kMaxEpsilonRelative]
    /// Seed of the probes' counter-based Gaussian generator (same result for any threads).
    uint64_t seed = 0x5EED5EEDull;
    /// The denoiser is handed this op's converged map (mcdn/skip.h; attribute
    /// mcdn:converged_tiles) so that its first run and its probes skip the same tiles.
    /// Converged tiles it passed through (y = x on the whole tile, as the ops do) get no
    /// probe: f'(x) = 1 there, so σ²f'(x) = σ² and SURE = σ² (the render's own error),
    /// exactly. Off: every pixel probed, the denoiser chooses its own tiles.
    SkipOptions skip;

    /// How far the denoiser's output at a pixel reaches into its input, in pixels: the sum
    /// of its stages' receptive radii (receptive_radius() of prefilter.h, nfor.h and cnn.h:
    /// 13, 77 and 30 at the defaults, nfor 64 after a prefilter; mcdn::chain_radius;
    /// mcdntool, run_chain and the Python module set it). When known (>= 0), frames above
    /// band_pixels run in horizontal bands, each with this many rows of halo (rounded up to
    /// whole converged tiles): the probe step and the probes' random numbers are the whole
    /// frame's, so the result is the whole-frame run's, and memory follows the band
    /// (ops/bands.h). -1 (not known: a Python callable): the whole frame at once.
    int denoiser_radius = -1;
    /// The denoiser may run on its input itself (dst = src), where it changes only the
    /// colour and the RGB extra AOVs, and reads no extra AOV when probed (the CNN; mcdntool
    /// and run_chain set it for a chain's cnn). When sure probes the caller's own one-band
    /// input that already has sure's channels (the chain's input read with room for them),
    /// the denoiser then runs in it and it becomes the result: no copy of the frame.
    bool denoiser_in_place = false;
    /// Pixels of one band, halos not counted: half of prefilter's and nfor's band_pixels, so
    /// that a band with its halos (up to 136 rows each side at 7680 wide) stays within theirs
    /// and they run it whole instead of cutting it again: at any frame size the peak is the
    /// render, sure's output and one band.
    int64_t band_pixels = kChainBandPixels;
    /// Called as the stage advances (mcdn/progress.h); empty: nothing is reported.
    ProgressCallback progress;
    /// The safety net, for any denoiser (the CNN's, which has no error estimate of its own):
    /// a tile of kConvergedTileSize² pixels where SURE says y is worse than the render —
    /// the sum over the tile of SURE / (y² + 0.01) without its largest 5% above that of
    /// σ² / (y² + 0.01), so that a few pixels (a firefly, a probe's noise) do not decide it
    /// (lib/src/skip/worse_tiles.h) — is the render there: colour and RGB extras y = x, and
    /// SURE = σ²f'(x) = σ², the render's own error, as on a tile passed through; a mix after
    /// it keeps the render there. On by default, as NFOR's own (docs/accuracy.md); false
    /// keeps the denoiser's tiles. The tiles are found and counted either way: the count is
    /// the attribute kSureFallbackCountAttribute when they fell back,
    /// kSureWorseCountAttribute when not (mcdntool -v prints it).
    bool fallback = true;
    /// Add channel sure.fallback: 1 on the tiles SURE finds worse (that fell back, with
    /// fallback), else 0.
    bool output_fallback = false;
};

/// Int attributes of sure's output: how many tiles SURE found worse than the render
/// (SureOptions::fallback) and sent back to it, or left as they were; absent when none.
constexpr const char* kSureFallbackCountAttribute = "mcdn:sure_fallback_count";
constexpr const char* kSureWorseCountAttribute = "mcdn:sure_worse_count";

/// Channel names the op writes (besides replacing the colour role by y = F(x)).
namespace sure_channels {
constexpr const char* kNoisy[3] = { "noisy.R", "noisy.G", "noisy.B" };  // x, for --mix
constexpr const char* kSure[3] = { "sure.R", "sure.G", "sure.B" };
constexpr const char* kDivergence[3] = { "sure.divergence.R", "sure.divergence.G",
                                         "sure.divergence.B" };  // sigma^2 f'(x)
constexpr const char* kResidual[3] = { "sure.residual.R", "sure.residual.G",
                                       "sure.residual.B" };  // ||y - x||^2
constexpr const char* kFallback = "sure.fallback";           // SureOptions::output_fallback
/// x of an extra AOV's channel (light groups; see NforOptions::denoise_extras), for --mix.
inline std::string noisy_extra(const std::string& channel)
{
    return "noisy." + channel;
}
}  // namespace sure_channels

/// Runs `denoiser` K + 1 times. dst = the denoised image (colour = y, every other channel
/// of src kept) plus noisy.*, sure.*, sure.divergence.*, sure.residual.* (written inside
/// `roi`, zero outside), and noisy.<channel> of each RGB extra AOV. Needs the colour and its
/// variance; half buffers are optional.
bool sure(ImageBuf& dst, const ImageBuf& src, const Denoiser& denoiser,
          const SureOptions& options = {}, ROI roi = {}, int nthreads = 0);
ImageBuf sure(const ImageBuf& src, const Denoiser& denoiser, const SureOptions& options = {},
              ROI roi = {}, int nthreads = 0);

}  // namespace mcdn
