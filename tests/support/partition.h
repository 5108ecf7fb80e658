// Extra AOVs that partition the beauty, like Blender light groups: two extras
// "<layer>.Combined_key" and "<layer>.Combined_fill" whose mean, halves and variances add up
// to the beauty's (the key gets a smooth share of it plus noise of its own, the fill the
// rest). For the tests of "extras denoised with the beauty's weights".
#pragma once

#include <cmath>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"
#include "mcdn_test.h"

namespace mcdn_test {

struct Partition {
    OIIO::ImageBuf image;
    mcdn::AovSpec spec;                  // the preset, and the extras unless found by name
    std::vector<int> beauty, key, fill;  // channel indices in `image`
};

/// `merged` plus the two extras; with own_halves = false the extras have means only. With
/// the cycles preset they are Blender light groups "<layer>.Combined_key.R" (found by name);
/// otherwise "Combined_key.R", named as extras in the returned spec.
inline Partition add_light_groups(const OIIO::ImageBuf& merged, const std::string& preset,
                                  bool own_halves)
{
    Partition p;
    p.spec.preset = preset;
    mcdn::AovSet aovs;
    std::string error;
    EXPECT_TRUE(mcdn::resolve_aovs(aovs, p.spec, merged.spec(), error)) << error;
    const std::string layer = preset == "cycles" ? "ViewLayer." : "";
    if (preset != "cycles")
        for (const char* group : { "key", "fill" }) {
            std::string g = std::string("Combined_") + group;
            EXPECT_TRUE(
                p.spec.parse_override("extra." + g + "=" + g + ".R," + g + ".G," + g + ".B", error))
                << error;
        }
    const OIIO::ImageSpec& spec = merged.spec();
    std::vector<std::string> names = spec.channelnames;
    // (channel to add, beauty channel it shares, is the key)
    struct Added {
        std::string name;
        int beauty;
        bool key;
    };
    std::vector<Added> added;
    const char* prefixes[] = { "", "A.", "B." };
    const mcdn::Role faces[] = { mcdn::Role::Color, mcdn::Role::ColorA, mcdn::Role::ColorB };
    for (int f = 0; f < (own_halves ? 3 : 1); ++f)
        for (const char* group : { "key", "fill" })
            for (int c = 0; c < 3; ++c)
                added.push_back(
                    { std::string(prefixes[f]) + layer + "Combined_" + group + "." + "RGB"[c],
                      aovs.channels(faces[f])[c], group[0] == 'k' });
    for (const Added& a : added)
        names.push_back(a.name);
    std::vector<float> px(spec.image_pixels() * spec.nchannels);
    merged.get_pixels(merged.roi(), OIIO::TypeDesc::FLOAT, px.data());
    auto key_share = [](int x, int y, float beauty) {
        float m = 0.5f + 0.4f * std::sin(0.3f * x) * std::cos(0.2f * y);
        float own = 0.05f * std::sin(12.9898f * x + 78.233f * y);  // noise of its own
        return m * beauty + own;
    };
    p.image = make_image(spec.width, spec.height, names, [&](int x, int y, int ch) {
        const float* pixel = px.data() + (size_t(y) * spec.width + x) * spec.nchannels;
        if (ch < spec.nchannels)
            return pixel[ch];
        const Added& a = added[ch - spec.nchannels];
        float key = key_share(x, y, pixel[a.beauty]);
        return a.key ? key : pixel[a.beauty] - key;
    });
    for (int c = 0; c < 3; ++c) {
        p.beauty.push_back(aovs.channels(mcdn::Role::Color)[c]);
        p.key.push_back(spec.nchannels + c);
        p.fill.push_back(spec.nchannels + 3 + c);
    }
    return p;
}

/// Largest |key + fill − beauty − offset| over pixels and channels, relative to the mean
/// |beauty|.
inline double partition_error(const OIIO::ImageBuf& out, const Partition& p, float offset = 0)
{
    const OIIO::ImageSpec& spec = out.spec();
    std::vector<float> px(spec.image_pixels() * spec.nchannels);
    out.get_pixels(out.roi(), OIIO::TypeDesc::FLOAT, px.data());
    double worst = 0, mean = 0;
    for (size_t i = 0; i < spec.image_pixels(); ++i)
        for (int c = 0; c < 3; ++c) {
            const float* pixel = px.data() + i * spec.nchannels;
            double d = pixel[p.key[c]] + pixel[p.fill[c]] - pixel[p.beauty[c]] - offset;
            worst = std::max(worst, std::abs(d));
            mean += std::abs(pixel[p.beauty[c]]);
        }
    mean /= 3.0 * spec.image_pixels();
    return worst / mean;
}

}  // namespace mcdn_test
