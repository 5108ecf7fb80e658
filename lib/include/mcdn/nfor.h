// Nonlinearly weighted first-order regression (NFOR; Bitterli et al. 2016, §5-6).
//
// The colour is fitted in every 19×19 window by a first-order model of the features,
// design [1, dx, dy, features - centre], with NL-means weights from the colour (§5.2). Half A
// is fitted with the features and weights of half B and vice versa; each window's fit is
// applied to the whole window and the overlapping fits are averaged (collaborative filtering).
// Two bandwidths are tried and chosen per pixel by the two-buffer MSE estimate (§5.3); a
// second pass filters the average of the two halves (§5.4).
#pragma once

#include <array>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/prefilter.h"
#include "mcdn/skip.h"
#include "mcdn/threads.h"

namespace mcdn {

/// Int attribute of nfor's output: how many tiles the safety net (NforOptions::fallback)
/// sent back to the render (of its band, in a banded run); absent when none.
constexpr const char* kNforFallbackCountAttribute = "mcdn:nfor_fallback_count";

struct NforOptions {
    /// Which channels are what: colour with its variance and halves; the features.
    AovSpec aovs;
    /// Extra feature channels used as regression features (see PrefilterOptions).
    std::vector<std::string> extra_features;

    // Regression (§5.2): 19×19 window, 7×7 patch for the colour NL-means weights.
    int window_radius = 9;
    int patch_radius = 3;
    /// Candidate NL-means bandwidths k (§5.3), chosen per pixel by the estimated MSE.
    std::array<float, 2> candidate_k = { 0.5f, 1.0f };
    /// Colour variance of a half buffer = this × variance of the mean.
    float variance_scale = 2.0f;

    // MSE and selection maps (§5.3): NL-means on the mean colour, 3×3 patch, 19×19 window.
    int map_window_radius = 9;
    int map_patch_radius = 1;
    float map_k = 1.0f;

    // Second pass (§5.4): regression of the averaged halves, 19×19 window, k = 1.
    int second_window_radius = 9;
    int second_patch_radius = 3;
    float second_k = 1.0f;

    /// Prefilter the features first (§5.1) unless src carries "mcdn:prefiltered" = 1
    /// (mcdntool --prefilter --nfor ran it already).
    bool prefilter_features = true;
    PrefilterOptions prefilter;  // its aovs and extra_features are taken from these options

    /// Denoise the AOV set's extra AOVs (AovSpec::extras, Blender light groups) with the
    /// beauty's regression weights and bandwidth selection, so that extras which add up to
    /// the beauty still do. Each extra costs about the three regressions of the beauty.
    bool denoise_extras = true;

    /// Heavy-tailed samples: a caustic or firefly pixel whose mean holds one sample worth
    /// a hundred or more of its neighbours. The regressions would spread it over their
    /// windows as blotches, black beside white (lib/src/outliers/outliers.h), so it is kept out
    /// of them: its inputs become its 5×5 neighbourhood's medians. It is an outlier when
    /// its variance of the mean exceeds outlier_variance_ratio times the neighbourhood's
    /// median, and its mean exceeds theirs by outlier_sigma of their standard deviations and
    /// by outlier_level_ratio times their value, the excess carried by one half buffer.
    enum class Outliers {
        /// The excess (render − median) is added back at the pixel after §5.4: the light
        /// stays where and in the amount the renderer put it (as in the render, a firefly
        /// stays a firefly), and the result converges to the render's mean. On sparse
        /// renders (many pixels pass the rule) this is the render's error: the denoising is
        /// lost there (docs/accuracy.md).
        Keep,
        /// The excess is dropped, as a renderer's sample clamp would: the lowest error of
        /// the three on every input measured, but a bias (the caustic loses the energy those
        /// rare paths carry on average) until the sample count is high enough that no
        /// pixel is an outlier.
        Drop,
        /// Not detected: the regressions see every pixel as rendered.
        Off,
    };
    Outliers outliers = Outliers::Drop;
    float outlier_sigma = 16.0f;
    float outlier_variance_ratio = 256.0f;
    float outlier_level_ratio = 64.0f;

    /// The safety net: a tile of kConvergedTileSize² pixels where NFOR's own per-pixel §5.3
    /// MSE estimate is above the render's variance of the mean — the sum over the tile of
    /// the estimates without their largest 5% against the sum of the variances, both
    /// weighted by relMSE's 1 / (ŷ² + 0.01), so that a few pixels (garbage, a heavy-tailed
    /// sample) do not decide it — is the render there (with outliers dropped, the render
    /// with their medians), since by the filter's own estimate it made the tile worse
    /// (lib/src/skip/worse_tiles.h). The count is the attribute kNforFallbackCountAttribute
    /// of the output (mcdntool -v prints it).
    bool fallback = true;
    /// Add channel nfor.fallback: 1 on the tiles that fell back, else 0.
    bool output_fallback = false;

    /// Add channels nfor.mse.R/G/B (estimated MSE of the chosen result, first pass) and
    /// nfor.selection.R/G/B (0: k = candidate_k[0], 1: candidate_k[1]).
    bool output_mse = false;
    bool output_selection = false;
    /// Write the features nfor prefiltered itself (§5.1) over their channels; default they
    /// keep the input's values.
    bool features_out = false;
    /// Use the half buffers when there are; false: the one-buffer path (the render and its
    /// variance, SURE for §5.3, no §5.4), as for a renderer that writes no halves.
    bool use_halves = true;

    /// Frames with more pixels run in horizontal bands of at most this many pixels (about
    /// twice 1920×1080), each with NFOR's receptive radius of extra rows above and below
    /// (77 rows at the default settings): the same output, memory that follows the band
    /// rather than the frame, more time (the halos are computed twice). 0: always the
    /// whole frame.
    int64_t band_pixels = kOpBandPixels;
    /// Converged tiles are the render, untouched, and cost nothing in any pass (their
    /// first-pass values for the neighbours' windows are the half buffers); features
    /// constant over the frame are left out of the prefilter and the regressions
    /// (mcdn/skip.h). Off: exactly the unskipped filter.
    SkipOptions skip;
    /// Called as the stage advances (mcdn/progress.h); empty: nothing is reported.
    ProgressCallback progress;

    /// Cross-frame NFOR (§8, spatio-temporal): neighbouring frames of the shot, nearest
    /// first (previous: t-1, t-2, ...; next: t+1, t+2, ...; at most 4 each, a shot's first
    /// and last frames have fewer), each with src's size, data window and channel names,
    /// and the motion role (Blender's Vector pass, mcdn/aov.h). The first pass's fits
    /// (§5.2) extend over their windows, aligned by the motion vectors, with the frame
    /// offset as one more feature; §5.3, §5.4 and the extra AOVs stay on this frame
    /// (lib/src/nfor/neighbour_frames.h). Runs the whole frame (band_pixels is not used).
    /// The frames are read, never written. Both empty: the single-frame filter.
    std::vector<const ImageBuf*> previous_frames, next_frames;
    bool cross_frame() const { return !previous_frames.empty() || !next_frames.empty(); }
};

/// Denoises the colour. dst = src (every channel kept) with the colour role's channels
/// replaced by the NFOR estimate, plus the optional nfor.* channels. Pixels outside `roi`
/// keep src's values. Output is finite and identical for any thread count.
bool nfor(ImageBuf& dst, const ImageBuf& src, const NforOptions& options = {}, ROI roi = {},
          int nthreads = 0);
ImageBuf nfor(const ImageBuf& src, const NforOptions& options = {}, ROI roi = {}, int nthreads = 0);

/// How far an output pixel reaches into the input, in pixels: 77 at the defaults, 64 when
/// the input is already prefiltered ("mcdn:prefiltered", as after a prefilter stage). The
/// halo of its bands, and its share of a chain's SureOptions::denoiser_radius.
int receptive_radius(const NforOptions& options, bool prefiltered);

}  // namespace mcdn
