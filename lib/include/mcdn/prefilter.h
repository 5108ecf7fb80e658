// NFOR feature prefilter (Bitterli et al. 2016, §5.1): NL-means cross-filtering of the
// feature passes with their half buffers, so the regression (nfor.h) sees clean features.
//
//   step 1: half A is filtered with weights computed on half B, and vice versa (the noise of
//           the weights is independent of the noise of the filtered image);
//   step 2: the mean of the filtered halves is filtered again, guided by itself, with the
//           residual variance (A' - B')² / 4 of the filtered halves (the reference
//           implementation's second-pass feature filter, §5.4).
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/skip.h"
#include "mcdn/threads.h"

namespace mcdn {

struct PrefilterOptions {
    /// Which channels are what (albedo, normal, depth, visibility and their faces).
    AovSpec aovs;
    /// Extra feature channels (names of the mean; faces "variance.", "A.", "B." + name).
    std::vector<std::string> extra_features;

    // Step 1, §5.1 and the reference implementation: 11×11 window, 7×7 patch, k = 0.5,
    // half-buffer variance = 2 × variance of the mean.
    int window_radius = 5;
    int patch_radius = 3;
    float k = 0.5f;
    float variance_scale = 2.0f;

    // Step 2 (§5.4): 5×5 window, 7×7 patch, k = 0.5 on the mean of the filtered halves.
    int second_window_radius = 2;
    int second_patch_radius = 3;
    float second_k = 0.5f;

    /// Frames with more pixels run in horizontal bands of at most this many pixels (with
    /// the filter's radius of extra rows each side), so memory follows the band: same
    /// output, a little more time. 0: always the whole frame.
    int64_t band_pixels = kOpBandPixels;
    /// Converged tiles of the colour (needs its variance role) are not filtered, and
    /// features constant over the frame are left as they are (mcdn/skip.h). nfor's own
    /// prefilter follows NforOptions::skip instead.
    SkipOptions skip;
    /// The op always writes the prefiltered features (they are what it makes). A chain
    /// (mcdntool, run_chain) puts the input's own features back into its output unless this
    /// is set (features-out=1), so that `--prefilter --nfor -o` changes only the colour.
    bool features_out = false;
    /// Called as the stage advances (mcdn/progress.h); empty: nothing is reported.
    ProgressCallback progress;
};

/// Prefilters every feature channel. dst = src with the features' mean, half A and half B
/// channels replaced by the prefiltered values (step 2, step 1, step 1) and their variance
/// channel by the residual variance of the filtered halves; sets "mcdn:prefiltered" = 1.
/// Pixels outside `roi` keep src's values. Errors are set on dst; returns false.
bool prefilter(ImageBuf& dst, const ImageBuf& src, const PrefilterOptions& options = {},
               ROI roi = {}, int nthreads = 0);
ImageBuf prefilter(const ImageBuf& src, const PrefilterOptions& options = {}, ROI roi = {},
                   int nthreads = 0);

/// How far an output pixel reaches into the input, in pixels (13 at the defaults): the halo
/// of its bands, and its share of a chain's SureOptions::denoiser_radius.
int receptive_radius(const PrefilterOptions& options);

}  // namespace mcdn
