// Heavy-tailed samples before NFOR's regressions and the KPCN's kernels (issue 22): a
// caustic path through glass, a firefly. Such a pixel's mean holds one sample worth
// hundreds or thousands of its neighbours, and its variance is as extreme. The regression
// cannot tell it from signal: the huge variance makes its NL-means distance to every patch
// small (all weights near 1), and the first-order fit of every window that holds it turns
// its energy into a ramp across the window — blotches of 20–40 px, negative beside
// positive, far worse than the render.
//
// So such pixels are taken out before §5.2: their mean, halves and variance become the
// medians of their neighbourhood, NFOR filters the rest as if they were ordinary, and after
// §5.4 their excess (render − that median) is added back at the pixel. The light stays
// where the renderer put it, in the amount it put there: the result at such a pixel is
// the denoised neighbourhood plus the render's outlier, never a spread of it.
//
// The KPCN op has the same problem: its kernels spread such a sample over their reach. It
// takes the same pixels out before the network (their diffuse and specular parts scaled
// with the colour, lib/src/cnn) and drops their excess.
//
// A pixel is such an outlier when, against the 24 others of its 5×5 neighbourhood
// (medians, so that one outlier does not hide another):
//   - its variance of the mean is more than `variance_ratio` times theirs, theirs above 0,
//     and
//   - its mean exceeds theirs by more than `sigma` of their standard deviations, and by
//     more than `level_ratio` times their value (plus a floor: 1% of the frame's mean): a
//     regression window of some 300 pixels absorbs a lesser excess as the noise it is;
//     their value is the larger of their median and their mean without their three
//     largest (which may be outliers of the same caustic). A sparse render — a dim light
//     that few paths reach, most pixels without a sample (no variance) or nearly black, a
//     few with one — has a median near 0 while the mean is the light: its samples are the
//     signal, and dropping them took a metal's highlights away;
//   - with half buffers, one half carries the excess: the other half's is at most half of
//     it (a bright feature both halves see is signal, however noisy).
// A pixel on a converged tile (mcdn/skip.h) is never one.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "core/extra_aovs.h"
#include "core/frame_facts.h"
#include "core/planar.h"
#include "skip/converged_tiles.h"

namespace mcdn {

/// The thresholds above (their defaults: NforOptions::outlier_*).
struct OutlierRule {
    float sigma = 0.0f;
    float variance_ratio = 0.0f;
    float level_ratio = 0.0f;
    /// Added to the neighbourhood's value in the level test, so that a dim pixel beside
    /// black ones (a corner a few paths reach) is not an outlier of nothing:
    /// kFloorOfMean × the frame's mean value.
    float level_floor = 0.0f;
    static constexpr double kFloorOfMean = 0.01;
    /// Neighbourhood radius (5×5): how far the detection reaches into the image.
    static constexpr int radius = 2;
};

/// The rule of these thresholds, its level floor from the frame's colour (kFloorOfMean × the
/// mean |colour|, three channels summed, as the rule compares them).
OutlierRule outlier_rule(float sigma, float variance_ratio, float level_ratio,
                         const ColorSums& frame);

/// The pixels taken out and what to add back at each, per channel: the beauty's excess and
/// each extra AOV's share of it.
struct OutlierPixels {
    std::vector<uint32_t> pixels;              // plane index, ascending
    std::vector<std::array<float, 3>> excess;  // per pixel
    /// [extra][pixel]: the part of `excess` that extra held (its share of the beauty).
    std::vector<std::vector<std::array<float, 3>>> extra_excess;

    bool empty() const { return pixels.empty(); }
};

/// Finds the outliers of the colour planes and takes them out: mean, variance and (when
/// given, else null) the halves at each outlier pixel replaced by the neighbourhood
/// medians; each extra's mean and halves by the extra less its share of the excess.
OutlierPixels take_out_outliers(Plane mean[3], Plane variance[3], Plane* half_a, Plane* half_b,
                                std::vector<ExtraPlanes>& extras, const ConvergedTiles& converged,
                                const OutlierRule& rule, int nthreads);

/// Adds the excess back at each outlier pixel of the denoised colour (the extras' shares:
/// ExtraAovs::put_back_outliers).
void put_back_outliers(const OutlierPixels& outliers, Plane denoised[3]);

}  // namespace mcdn
