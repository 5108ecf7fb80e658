// Progressive denoising: mix the render x and the denoised y per pixel,
//   z = x + alpha' (y - x),
// with alpha from a model and bounded by a t-test so that z converges to the render as the
// sample count grows (Firmino et al. 2022, §4).
//
// Reads what mcdn::sure writes: the colour role holds y, noisy.* holds x, and sure.*,
// sure.divergence.*, sure.residual.* hold SURE, sigma^2 f'(x) and ||y - x||^2; the colour
// variance role holds Var[x].
#pragma once

#include <string>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/skip.h"
#include "mcdn/threads.h"

namespace mcdn {

struct MixOptions {
    AovSpec aovs;

    enum class Model {
        /// §4.3: the mixing network h_NN (5x5 conv to 48, two 3x3/48 residual blocks,
        /// 3x3 conv to 3 outputs per channel, f_act), trained by training/mix on our
        /// denoisers' outputs and their SURE; weights from `weights` (default: the network of
        /// the denoiser that made src, default_mix_weights()).
        Net,
        /// Eq. 9 with its noisy terms averaged over a (2r+1)^2 box:
        /// alpha = (<sigma^2> - <sigma^2 f'(x)>) / <||y - x||^2>, clipped to [0, 1].
        Analytic,
    };
    Model model = Model::Net;
    /// Weights file of the mixing network (Model::Net); empty: default_mix_weights() of the
    /// denoiser src's "mcdn:denoiser" attribute names.
    std::string weights;
    /// Neighbourhood radius of the analytic model's averages (21x21): the relative noise of
    /// <||y - x||^2> falls as 1/(2r+1) and pulls alpha below 1 on smooth regions, costing
    /// MSE against the denoiser alone; 11x11 costs about twice what 21x21 does (tests/mix).
    int analytic_radius = 10;
    /// Model::Net: alpha is at least the analytic model's (eq. 9 on neighbourhood averages).
    /// Each errs toward the render in its own places — the analytic alpha on smooth regions
    /// (the noise of its averages), the network on renders unlike its training data (the
    /// Tungsten scenes) — and neither is high where the denoiser is visibly biased (a large
    /// ||y - x||^2 lowers eq. 9); the t-test still bounds the result.
    bool analytic_floor = true;
    /// Either model: where the render's variance exceeds this many times y^2 + 0.01 (an
    /// outlier of its own variance: the network's arctan error inputs read such pixels as
    /// saturated, the analytic model's box averages spread them over 441 pixels), alpha is
    /// at least the pixel's own eq. 9 (lib/src/mix/outlier_floor.cpp). 0 disables the bound.
    float outlier_relative_variance = 0.3f;
    /// Either model: where it exceeds this many times y^2 + 0.01, alpha = 1 before the
    /// t-test (the render pixel's value says little about its mean; eq. 9 is noise there).
    /// 0 disables it.
    float drop_relative_variance = 1.5f;

    // The t-test bound, eq. 12-18.
    bool t_test = true;
    int t_radius = 5;              // 11x11 neighbourhood N_p
    float t_shift = 4.2f;          // c
    float t_strength = 2.0f;       // a
    float t_sigma_scale = 100.0f;  // sigma_s = min(sqrt(Var[x-bar]), 1) * 100
    float t_epsilon = 1e-6f;       // eq. 17

    /// Add mix.alpha.R/G/B (alpha', the final per-pixel mix).
    bool output_alpha = false;

    /// z = x, α' = 0, on tiles the denoiser returned unchanged (y = x at every pixel, as the
    /// ops leave converged tiles: no α can change z there); the network does not run on them
    /// (mcdn/skip.h). z is the same as without skipping. The t-test's α' = 0 elsewhere is
    /// not known before α (it tests α(y − x)), so those tiles still run.
    SkipOptions skip;

    /// Frames with more pixels run in horizontal bands of at most this many pixels, each
    /// with alpha's reach of extra rows above and below (the model's neighbourhood plus the
    /// t-test's, rounded up to 32): the same output (the network's within float round-off:
    /// its tiles fall differently), memory that follows the band. 0: the whole frame.
    int64_t band_pixels = kOpBandPixels;
    /// Called as the stage advances (mcdn/progress.h); empty: nothing is reported.
    ProgressCallback progress;
};

/// The mixing network trained for `denoiser`'s outputs (PD §5.3 trains one per denoiser):
/// mix_cnn.mcdnw for "cnn" (the KPCN op), mix_oidn.mcdnw for "oidn" (OIDN's network, PD §6),
/// mix.mcdnw for "nfor" and for any other (with a
/// deliberately biased one, bench_mix's blur: models/README.md), in the models directory
/// ($MCDN_MODELS when set, else share/mcdenoise/models installed with the library).
/// mix() asks for the denoiser its input names in the "mcdn:denoiser" attribute, which the
/// nfor and cnn ops set and sure keeps; a Python or C++ callable denoiser may set it too.
std::string default_mix_weights(const std::string& denoiser = "nfor");

/// How far alpha' at a pixel reaches into mix()'s input: the model's neighbourhood (the
/// network of `denoiser` unless MixOptions::weights names one) and the t-test's; -1 when the
/// network cannot be read.
int receptive_radius(const MixOptions& options, const std::string& denoiser = "nfor");

/// dst = src with the colour role replaced by z (and mix.alpha.* if asked for). Pixels
/// outside `roi` keep src's colour. Finite, identical for any thread count. dst may be src
/// (in place: no copy of the frame when it is one band).
bool mix(ImageBuf& dst, const ImageBuf& src, const MixOptions& options = {}, ROI roi = {},
         int nthreads = 0);
ImageBuf mix(const ImageBuf& src, const MixOptions& options = {}, ROI roi = {}, int nthreads = 0);

}  // namespace mcdn
