// A firefly planted in a render, as one sample of a caustic path would land — in one half
// buffer, its mean and a variance to match — and how far a denoiser spread it. For the tests
// of the heavy-tailed samples the denoisers take out (lib/src/outliers/outliers.h).
#pragma once

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn_test.h"

namespace mcdn_test {

/// The colour role's channels of `image` under `spec`: mean, variance, half A, half B.
struct ColorChannels {
    std::vector<int> mean, variance, half_a, half_b;
};
inline ColorChannels color_channels(const OIIO::ImageBuf& image, const mcdn::AovSpec& spec)
{
    mcdn::AovSet aovs;
    std::string error;
    EXPECT_TRUE(mcdn::resolve_aovs(aovs, spec, image.spec(), error)) << error;
    return { aovs.channels(mcdn::Role::Color), aovs.channels(mcdn::Role::ColorVariance),
             aovs.channels(mcdn::Role::ColorA), aovs.channels(mcdn::Role::ColorB) };
}

/// One sample worth `times` the pixel's mean landed in half A at (x, y): the mean gains
/// `excess`, half A twice that, and the variance of the mean the square of the excess
/// (the spread of the seeds' means it would leave).
inline OIIO::ImageBuf with_firefly(const OIIO::ImageBuf& src, const mcdn::AovSpec& spec, int x,
                                   int y, float times, float* excess_out = nullptr)
{
    OIIO::ImageBuf out;
    out.copy(src);
    const ColorChannels ch = color_channels(src, spec);
    std::vector<float> px(size_t(out.nchannels()));
    out.getpixel(x, y, 0, px.data(), out.nchannels());
    for (int c = 0; c < 3; ++c) {
        const float excess = times * std::max(px[size_t(ch.mean[c])], 0.01f);
        if (excess_out)
            excess_out[c] = excess;
        px[size_t(ch.mean[c])] += excess;
        px[size_t(ch.half_a[c])] += 2.0f * excess;
        px[size_t(ch.variance[c])] += excess * excess;
    }
    out.setpixel(x, y, 0, px.data(), out.nchannels());
    return out;
}

/// Largest |a − b| of the colour over the pixels within `reach` of (x, y), without (x, y)
/// itself, relative to b + 0.05.
inline float largest_change_around(const OIIO::ImageBuf& a, const OIIO::ImageBuf& b,
                                   const std::vector<int>& color, int x, int y, int reach)
{
    float largest = 0.0f;
    for (int v = std::max(0, y - reach); v <= std::min(a.spec().height - 1, y + reach); ++v)
        for (int u = std::max(0, x - reach); u <= std::min(a.spec().width - 1, x + reach); ++u)
            if (u != x || v != y)
                for (int c : color) {
                    const float reference = b.getchannel(u, v, 0, c);
                    largest = std::max(largest, std::fabs(a.getchannel(u, v, 0, c) - reference)
                                                    / (std::fabs(reference) + 0.05f));
                }
    return largest;
}

}  // namespace mcdn_test
