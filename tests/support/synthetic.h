// Synthetic renders with a known ground truth, for property tests of SURE and the mix.
#pragma once

#include <cmath>
#include <functional>
#include <random>

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/aov.h"
#include "mcdn/sure.h"

#include "mcdn_test.h"

namespace mcdn_test {

/// Channel layout of the generic preset with halves: R,G,B, variance.*, A.*, B.*.
inline std::vector<std::string> generic_channels()
{
    return { "R",   "G",   "B",   "variance.R", "variance.G", "variance.B",
             "A.R", "A.G", "A.B", "B.R",        "B.G",        "B.B" };
}

/// A render of `truth` with per-pixel variance of the mean `variance`: halves A and B are
/// independent with variance 2*variance each, and the render is their mean.
inline OIIO::ImageBuf noisy_render(int w, int h, const std::function<float(int, int, int)>& truth,
                                   float variance, unsigned seed)
{
    std::mt19937 rng(seed);
    std::normal_distribution<float> half_noise(0.0f, std::sqrt(2.0f * variance));
    std::vector<float> a(size_t(w) * h * 3), b(a.size());
    for (size_t i = 0; i < a.size(); ++i) {
        a[i] = half_noise(rng);
        b[i] = half_noise(rng);
    }
    return make_image(w, h, generic_channels(), [&](int x, int y, int c) {
        size_t i = (size_t(y) * w + x) * 3 + c % 3;
        float mu = truth(x, y, c % 3);
        switch (c / 3) {
        case 0: return mu + 0.5f * (a[i] + b[i]);
        case 1: return variance;
        case 2: return mu + a[i];
        default: return mu + b[i];
        }
    });
}

/// The ground truth as an RGB image.
inline OIIO::ImageBuf truth_image(int w, int h, const std::function<float(int, int, int)>& truth)
{
    return make_image(w, h, { "R", "G", "B" }, truth);
}

/// A linear denoiser with a known Jacobian diagonal: a (2r+1)^2 box blur of the average of
/// the two halves, written into the colour channels (df_i/dx_i = 1/(2r+1)^2 inside).
inline mcdn::Denoiser box_denoiser(int radius)
{
    return [radius](OIIO::ImageBuf& dst, const OIIO::ImageBuf& src) {
        OIIO::ImageBuf halves =
            OIIO::ImageBufAlgo::add(OIIO::ImageBufAlgo::channels(src, 3, { 6, 7, 8 }),
                                    OIIO::ImageBufAlgo::channels(src, 3, { 9, 10, 11 }));
        halves = OIIO::ImageBufAlgo::mul(halves, 0.5f);
        int size = 2 * radius + 1;
        OIIO::ImageBuf kernel = OIIO::ImageBufAlgo::make_kernel("box", size, size);
        OIIO::ImageBuf blurred = OIIO::ImageBufAlgo::convolve(halves, kernel);
        dst.copy(src, OIIO::TypeDesc::FLOAT);
        OIIO::ImageBufAlgo::paste(dst, 0, 0, 0, 0, blurred);
        return true;
    };
}

inline mcdn::AovSpec generic_spec()
{
    mcdn::AovSpec spec;
    spec.preset = "generic";
    return spec;
}

/// Mean of channel c over the image.
inline double channel_mean(const OIIO::ImageBuf& buf, int c)
{
    auto stats = OIIO::ImageBufAlgo::computePixelStats(buf);
    return stats.avg[c];
}

}  // namespace mcdn_test
