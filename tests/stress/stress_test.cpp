// Numerical stress: every op fed NaN, Inf, negative, huge, denormal values, zero variance,
// constant and collinear features, fireflies, half-float buffers and odd sizes. Each op must
// either succeed with finite values in every channel it writes, or fail with a message.
#include <algorithm>
#include <cmath>
#include <functional>

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/chain.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/sure.h"

#include "mcdn_test.h"

using namespace mcdn;
using mcdn_test::make_image;

namespace {

// Generic layout with every face of colour, albedo, normal and depth.
std::vector<std::string> channels()
{
    std::vector<std::string> names;
    for (const char* prefix : { "", "variance.", "A.", "B." })
        for (const char* base :
             { "R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "Z" })
            names.push_back(std::string(prefix) + base);
    return names;
}

// A plausible render: smooth colour with noise, features with structure.
float plausible(int x, int y, int c)
{
    int face = c / 10, k = c % 10;
    float noise = float(((x * 7919 + y * 104729 + c * 31) % 97) - 48) / 480.0f;
    if (face == 1)
        return k < 3 ? 0.01f : 0.001f;  // variances
    float base = k < 3   ? 0.3f + 0.01f * x + 0.2f * (k == 1)
                 : k < 6 ? 0.5f + 0.1f * ((x / 4) % 2)
                 : k < 9 ? (k == 8 ? 1.0f : 0.0f)
                         : 2.0f + 0.05f * y;
    return base + (k < 3 ? noise : 0.1f * noise);
}

struct Case {
    std::string name;
    int width, height;
    std::function<float(int, int, int, float)> edit;  // (x, y, channel, plausible value)
    bool half = false;
};

std::vector<Case> cases()
{
    auto at = [](int px, int py, std::function<bool(int)> channel, float value) {
        return [=](int x, int y, int c, float v) {
            return x == px && y == py && channel(c) ? value : v;
        };
    };
    auto color = [](int c) { return c % 10 < 3 && c / 10 != 1; };
    auto feature = [](int c) { return c % 10 >= 3 && c / 10 != 1; };
    auto feature_variance = [](int c) { return c / 10 == 1 && c % 10 >= 3; };
    auto keep = [](int, int, int, float v) { return v; };
    return {
        { "plausible", 24, 20, keep },
        { "nan colour", 24, 20, at(5, 5, color, NAN) },
        { "inf colour", 24, 20, at(5, 5, color, INFINITY) },
        { "-inf feature", 24, 20, at(7, 3, feature, -INFINITY) },
        { "nan feature variance", 24, 20,
          [=](int x, int y, int c, float v) { return feature_variance(c) && x < 3 ? NAN : v; } },
        { "negative colour", 24, 20,
          [=](int x, int, int c, float v) { return color(c) && x % 3 == 0 ? -v : v; } },
        { "1e30", 24, 20, at(10, 10, color, 1e30f) },
        { "firefly 1e6", 24, 20, at(12, 9, color, 1e6f) },
        { "denormals", 24, 20,
          [](int, int, int c, float v) { return c / 10 == 1 ? 1e-40f : v * 1e-39f; } },
        { "zero variance", 24, 20,
          [](int, int, int c, float v) { return c / 10 == 1 ? 0.0f : v; } },
        { "constant features", 24, 20,
          [=](int, int, int c, float v) { return feature(c) ? 0.5f : v; } },
        { "collinear features", 24, 20,
          [=](int x, int, int c, float v) { return feature(c) ? 0.1f * x : v; } },
        { "all zero", 24, 20, [](int, int, int, float) { return 0.0f; } },
        { "half float", 24, 20, keep, true },
        { "1x1", 1, 1, keep },
        { "1xN", 1, 17, keep },
        { "Nx1", 19, 1, keep },
        { "odd 7x13", 7, 13, keep },
    };
}

ImageBuf input(const Case& k)
{
    ImageBuf buf = make_image(k.width, k.height, channels(), [&](int x, int y, int c) {
        return k.edit(x, y, c, plausible(x, y, c));
    });
    if (k.half)
        buf = buf.copy(OIIO::TypeDesc::HALF);
    return buf;
}

AovSpec generic()
{
    AovSpec spec;
    spec.preset = "generic";
    return spec;
}

// Channels an op writes: `own` (colour for denoisers, features for the prefilter), and every
// channel src did not have. Channels it passes through keep whatever the input held.
void expect_finite_outputs(const ImageBuf& out, const ImageBuf& src, const std::string& what,
                           const std::vector<std::string>& own)
{
    std::vector<int> written;
    for (int c = 0; c < out.nchannels(); ++c) {
        const std::string& name = out.spec().channelnames[c];
        if (src.spec().channelindex(name) < 0
            || std::find(own.begin(), own.end(), name) != own.end())
            written.push_back(c);
    }
    std::vector<float> px(out.nchannels());
    for (int y = out.ybegin(); y < out.yend(); ++y)
        for (int x = out.xbegin(); x < out.xend(); ++x) {
            out.getpixel(x, y, px.data(), out.nchannels());
            for (int c : written)
                ASSERT_TRUE(std::isfinite(px[c])) << what << ": " << out.spec().channelnames[c]
                                                  << " at (" << x << ", " << y << ") is " << px[c];
        }
}

void check(const std::string& op, const Case& k, bool ok, const ImageBuf& out, const ImageBuf& src,
           const std::vector<std::string>& own = { "R", "G", "B" })
{
    std::string what = op + " on '" + k.name + "'";
    if (!ok) {
        EXPECT_FALSE(out.geterror().empty()) << what << " failed without a message";
        return;
    }
    expect_finite_outputs(out, src, what, own);
}

}  // namespace

TEST(Stress, Prefilter)
{
    for (const auto& k : cases()) {
        ImageBuf src = input(k), out;
        PrefilterOptions o;
        o.aovs = generic();
        std::vector<std::string> features;
        for (const char* prefix : { "", "variance.", "A.", "B." })
            for (const char* f : { "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "Z" })
                features.push_back(std::string(prefix) + f);
        check("prefilter", k, prefilter(out, src, o), out, src, features);
    }
}

TEST(Stress, Nfor)
{
    for (const auto& k : cases()) {
        ImageBuf src = input(k), out;
        NforOptions o;
        o.aovs = generic();
        o.output_mse = o.output_selection = true;
        check("nfor", k, nfor(out, src, o), out, src);
    }
}

TEST(Stress, SureAndMix)
{
    for (const auto& k : cases()) {
        ImageBuf src = input(k), with_sure, mixed;
        ChainOptions o;
        o.aovs = generic();
        o.stages = { "nfor", "sure" };
        bool ok = run_chain(with_sure, src, o);
        check("nfor+sure", k, ok, with_sure, src);
        if (!ok)
            continue;
        MixOptions m;
        m.aovs = generic();
        m.output_alpha = true;
        check("mix", k, mix(mixed, with_sure, m), mixed, src);
    }
}

TEST(Stress, SeveralThreadsAgreeOnBadInput)
{
    for (const auto& k : cases()) {
        ImageBuf src = input(k), one, two;
        NforOptions o;
        o.aovs = generic();
        bool ok1 = nfor(one, src, o, {}, 1), ok2 = nfor(two, src, o, {}, 2);
        ASSERT_EQ(ok1, ok2) << k.name;
        if (ok1) {
            EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, two, 0, 0).maxerror, 0.0) << k.name;
        }
    }
}
