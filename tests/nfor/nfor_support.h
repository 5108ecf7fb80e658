// Synthetic renders for the NFOR tests: a clean colour and features, independent Gaussian
// noise in the two half buffers, the generic preset's channel layout.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn_test.h"

namespace nfor_test {

/// Deterministic standard normal noise per (x, y, stream).
inline float gauss(int x, int y, int stream)
{
    auto hash = [](uint32_t v) {
        v ^= v >> 16;
        v *= 0x7feb352dU;
        v ^= v >> 15;
        v *= 0x846ca68bU;
        v ^= v >> 16;
        return v;
    };
    uint32_t h1 =
        hash(uint32_t(x) * 73856093U ^ uint32_t(y) * 19349663U ^ uint32_t(stream) * 83492791U);
    uint32_t h2 = hash(h1 + 0x9e3779b9U);
    double u1 = (h1 + 0.5) / 4294967296.0, u2 = (h2 + 0.5) / 4294967296.0;
    return float(std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2));
}

struct Scene {
    int width = 64, height = 64;
    std::function<float(int, int, int)> color;   // clean colour (x, y, channel)
    std::function<float(int, int, int)> albedo;  // clean feature
    float sigma_half = 0.1f;                     // noise of one half buffer
};

inline std::vector<std::string> generic_channels()
{
    std::vector<std::string> names;
    for (const char* prefix : { "", "variance.", "A.", "B." }) {
        for (const char* c : { "R", "G", "B" })
            names.push_back(std::string(prefix) + c);
        for (const char* c : { "albedo.R", "albedo.G", "albedo.B" })
            names.push_back(std::string(prefix) + c);
    }
    return names;
}

/// Channels: R,G,B, albedo.R/G/B, then the same with variance., A., B. prefixes.
inline OIIO::ImageBuf render(const Scene& s)
{
    return mcdn_test::make_image(s.width, s.height, generic_channels(), [&](int x, int y, int ch) {
        int face = ch / 6, c = ch % 6;
        bool is_color = c < 3;
        int cc = c % 3;
        float clean = is_color ? s.color(x, y, cc) : s.albedo(x, y, cc);
        float sigma = is_color ? s.sigma_half : 0.0f;
        float a = clean + sigma * gauss(x, y, 2 * c);
        float b = clean + sigma * gauss(x, y, 2 * c + 1);
        switch (face) {
        case 0: return 0.5f * (a + b);
        case 1: return 0.5f * sigma * sigma;  // variance of the mean of two halves
        case 2: return a;
        default: return b;
        }
    });
}

inline double mse_against(const OIIO::ImageBuf& img, const Scene& s)
{
    double sum = 0;
    for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x)
            for (int c = 0; c < 3; ++c) {
                double d = img.getchannel(x, y, 0, c) - s.color(x, y, c);
                sum += d * d;
            }
    return sum / (3.0 * s.width * s.height);
}

inline bool all_finite(const OIIO::ImageBuf& img)
{
    std::vector<float> px(img.spec().image_pixels() * img.nchannels());
    img.get_pixels(img.roi(), OIIO::TypeDesc::FLOAT, px.data());
    for (float v : px)
        if (!std::isfinite(v))
            return false;
    return true;
}

inline double relmse(const OIIO::ImageBuf& img, const std::vector<int>& channels,
                     const std::string& reference)
{
    OIIO::ImageBuf ref;
    EXPECT_TRUE(mcdn::read_image(ref, reference)) << ref.geterror();
    mcdn::MetricsOptions mo;
    mo.image_channels = channels;
    mcdn::Metrics m;
    std::string error;
    EXPECT_TRUE(mcdn::compute_metrics(m, img, ref, mo, error)) << error;
    return m.relmse;
}

/// A shot of a textured plane moving vx, vy pixels a frame, each frame with its own noise,
/// the generic channels plus Blender's Vector pass as motion.X/Y/Z/W.
struct Shot {
    /// The generic preset with the motion channels named.
    static mcdn::AovSpec aovs()
    {
        mcdn::AovSpec spec;
        spec.preset = "generic";
        spec.overrides["motion"] = { "motion.X", "motion.Y", "motion.Z", "motion.W" };
        return spec;
    }

    int width = 64, height = 64;
    float vx = 0, vy = 0;  // motion of the content per frame, pixels (y down)
    float sigma_half = 0.15f;
    /// Motion channels written: the true motion, or none (0) when false.
    bool true_motion = true;

    /// The albedo explains the texture; the shading, which varies over a few windows, no
    /// feature explains.
    float albedo(float x, float y, int c) const
    {
        return 0.5f + 0.4f * std::sin(0.41f * x + 0.3f * c) * std::cos(0.27f * y);
    }
    float color(int t, int x, int y, int c) const
    {
        const float u = x - vx * t, v = y - vy * t;  // where the content was at frame 0
        return 0.05f + 0.9f * albedo(u, v, c) * (0.6f + 0.4f * std::sin(0.05f * u + 0.035f * v));
    }
    OIIO::ImageBuf frame(int t) const
    {
        std::vector<std::string> names = generic_channels();
        for (const char* c : { "motion.X", "motion.Y", "motion.Z", "motion.W" })
            names.push_back(c);
        return mcdn_test::make_image(width, height, names, [&](int x, int y, int ch) -> float {
            if (ch >= 24) {  // Blender's convention: previous at p + (X, -Y), next p + (-Z, W)
                if (!true_motion)
                    return 0.0f;
                const float m[4] = { -vx, vy, -vx, vy };
                return m[ch - 24];
            }
            const int face = ch / 6, c = ch % 6, cc = c % 3;
            const float u = x - vx * t, v = y - vy * t;
            const float clean = c < 3 ? color(t, x, y, cc) : albedo(u, v, cc);
            const float sigma = c < 3 ? sigma_half : 0.0f;
            const float a = clean + sigma * gauss(x, y, 2 * c + 100 * t);
            const float b = clean + sigma * gauss(x, y, 2 * c + 1 + 100 * t);
            switch (face) {
            case 0: return 0.5f * (a + b);
            case 1: return 0.5f * sigma * sigma;
            case 2: return a;
            default: return b;
            }
        });
    }
    double mse(const OIIO::ImageBuf& img, int t) const
    {
        double sum = 0;
        int n = 0;
        for (int y = 8; y < height - 8; ++y)  // away from where the motion leaves the frame
            for (int x = 8; x < width - 8; ++x)
                for (int c = 0; c < 3; ++c, ++n) {
                    const double d = img.getchannel(x, y, 0, c) - color(t, x, y, c);
                    sum += d * d;
                }
        return sum / n;
    }
};

/// An op's options for a Shot: its AOV spec.
template <class Options> Options shot_options()
{
    Options o;
    o.aovs = Shot::aovs();
    return o;
}

}  // namespace nfor_test
