// Choosing between two denoisers by their error estimates, SURE (ChooseEstimate::Sure, the
// first rule) or the halves' (Halves, below). Progressive Denoising §3.2 observes that
// SURE's per-pixel estimate is too noisy to decide alone but that its local averages follow
// the true error, and "could form the basis of a decision"; NFOR §5.3 weighs its candidates
// by error estimates filtered over a window, and Zheng et al. (PD §2.2) combine denoisers by
// their MSE estimates. Per pixel p, for each candidate k (a, b):
//
//   E_k(p) = sum over the (2 window + 1)^2 box around p, and over R, G, B, of
//            SURE_k / (ybar^2 + 0.01 + Var)      ybar = (y_a + y_b) / 2, Var the render's
//   w0     = E_a / (E_a + E_b)                  each E at least 1e-9: b's share of the
//                                               inverse errors (w0 = 1: b alone)
//   w      = w0 averaged over the (2 blend + 1)^2 box around p
//   y      = y_a + w (y_b - y_a), each RGB extra AOV likewise (the same w: the extras that
//            add up to the beauty still do)
//
// The error counts relative to the value, as relMSE does, and to the render's variance too:
// SURE's own noise grows with the variance (its terms (y - x)^2, 2 Var f' and Var each
// swing by about Var), so a firefly's estimate, which could decide a window alone, weighs
// as little as it tells. On our evaluation inputs (bench/results/choose.md),
// without Var in the scale, one scene's choice came out 3.4x worse than its better
// candidate; a hard choice of the lower E (NFOR's rule) was up to 7% worse than it.
// The result's SURE: its residual ||y - x||^2 exactly, its divergence (1 - w) div_a +
// w div_b (w held fixed: it follows windows of hundreds of pixels), so that a mix after it
// (PD §4) reads the chosen image's own estimate.
//
// Where the render has half buffers and choose is handed the denoiser that made a
// (ChooseEstimate::Halves: --denoise's NFOR beside the CNN), the weight comes from the
// halves instead of SURE: NFOR §5.3's two-buffer estimate, for any two denoisers. Each runs
// on half A and on half B as renders of their own (choose/half_render.h: a_A is a's
// denoiser on A, b_A the other's), and the other half is a target whose noise is
// independent of what was denoised. With d_H = b_H - a_H and s = ybar^2 + 0.01 + Var:
//
//   N(p) = sum over the window and R, G, B of [d_A (B - a_A) + d_B (A - a_B)] / s
//   D(p) = the same sum of (d_A^2 + d_B^2) / s
//   S(p) = sqrt(the same sum of (d_A^2 + d_B^2) 2 Var / s^2)    N's standard error (a
//                                                               half's variance is 2 Var)
//   w0   = N / D clamped to [0, 1] where N > kChooseSignificance S, else 0
//
// N / D is the blend weight of b that minimizes the window's estimated error of the halves'
// results; b weighs only where the halves show that it lowers the error by more than their
// noise could. Nothing in it assumes Gaussian noise or a small probe, where SURE of the
// colour was from below 0 to 10x each denoiser's error over a frame (docs/accuracy.md).
// Measured on 41 inputs (bench/choose_rules, the op against SURE's share): geometric mean
// over the better of the CNN and NFOR 0.91 against 0.99, worst 1.11 against 1.35. Cost: a's
// and the other denoiser's runs on each half, besides the other's SURE (its divergence is
// the result's, for the mix).
//
// a is the image src holds (a denoiser's result after sure: its colour, sure.*, noisy.*);
// b is `other` run by choose itself on the render that sure recorded (noisy.*), with its own
// SURE (K probes, mcdn/sure.h). --denoise runs it after --cnn --sure with NFOR (prefilter,
// nfor) as b where the render has half buffers, and after --oidn --sure with the CNN as b.
#pragma once

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn/progress.h"
#include "mcdn/sure.h"

namespace mcdn {

/// Which estimate weighs the two denoisers (above).
enum class ChooseEstimate { Sure, Halves };

/// The halves' rule weighs b where N is above this many standard errors of it.
constexpr double kChooseSignificance = 2.0;

struct ChooseOptions {
    AovSpec aovs;
    /// Halves needs `before` and the colour's half buffers; where the half renders' AOVs do
    /// not resolve (an --aov override names a half), SURE weighs, and
    /// kChooseEstimateAttribute says why.
    ChooseEstimate estimate = ChooseEstimate::Sure;
    /// The denoiser that made a (the chain's before --sure), which Halves runs on each half.
    Denoiser before;
    /// `other` as Halves runs it on each half, where only its colour is read: the stage hands
    /// it with extras=0 (no light pass regressed). Empty: `other`.
    Denoiser other_on_halves;
    /// The window's radius: 8 sums SURE over 17×17 pixels (PD Fig. 3: single pixels decide
    /// nothing; NFOR §5.3 filters its error maps over a 19×19 window).
    int window_radius = 8;
    /// The weight's smoothing radius (9×9), as NFOR §5.3 filters its selection maps.
    int blend_radius = 4;
    /// `other` weighs only where the render's relative variance Var / (y^2 + 0.01) (y the
    /// image before), averaged over R, G, B and the window, is below this; where it weighs
    /// nowhere, choose does not run it. 0: everywhere (NFOR beside the CNN).
    /// kChooseNetworksMaxNoise for a network beside another.
    float max_noise = 0;
    /// SURE of `other` (probes, eps, seed, its safety net); aovs and progress are this op's.
    SureOptions sure;
    /// How far `other` reaches (SureOptions::denoiser_radius); -1: not known.
    int other_radius = -1;
    /// `other` is NFOR, whose input is the colour's half buffers: without them it would run
    /// its one-buffer path, which choose was not measured with; choose says so before it runs.
    bool other_needs_halves = false;
    /// Handed to the stage that makes `other` (NforOptions::denoise_extras for --denoise's
    /// NFOR): its extras are denoised as the image before's were (extras=0: as rendered).
    bool denoise_extras = true;
    /// Add channel choose.weight: w (0: the image before, 1: other's).
    bool output_weight = false;
    ProgressCallback progress;
};

/// ChooseOptions::max_noise for two networks (--choose:with=cnn after --oidn, --denoise's
/// plan with OIDN's weights): where the render is noisier, their SUREs are not equally wrong
/// (on box 16 spp the CNN's says 580 where its error is 2186, OIDN's 1028 for 1353) and the
/// choice followed them to results up to 34 % worse than OIDN's; below it, on the 35 inputs of
/// docs/accuracy.md, none is worse than OIDN's by more than 2 %. The largest bound of 0.002,
/// 0.003, 0.005, 0.01 and 0.03 with none worse (0.005: one input 4 % worse, 0.03: one 23 %).
constexpr float kChooseNetworksMaxNoise = 0.003f;

/// Float attribute of choose's output: the mean of w over the frame (how much of the
/// result is `other`'s).
constexpr const char* kChooseShareAttribute = "mcdn:choose_share";
/// String attribute of choose's output: the estimate that weighed ("halves", "SURE", or
/// "SURE (...)" saying why not the halves).
constexpr const char* kChooseEstimateAttribute = "mcdn:choose_estimate";

/// dst = src with the colour, its RGB extras and sure.*, sure.divergence.*, sure.residual.*
/// replaced by the choice above between src's denoised image (a) and other's (b), which
/// choose runs with its SURE on the render src's noisy.* records. Needs what sure adds and
/// the colour's variance. dst may be src: a frame in memory is then where the render is
/// rebuilt and b made (a's values kept apart, a third of the frame's channels on Blender's
/// passes), not a copy of it.
bool choose(ImageBuf& dst, const ImageBuf& src, const Denoiser& other,
            const ChooseOptions& options = {}, ROI roi = {}, int nthreads = 0);
ImageBuf choose(const ImageBuf& src, const Denoiser& other, const ChooseOptions& options = {},
                ROI roi = {}, int nthreads = 0);

/// How far a pixel of choose's result reaches into the render, past `other`'s reach.
int receptive_radius(const ChooseOptions& options);

}  // namespace mcdn
