// Cross-frame NFOR (§8): the neighbouring frames of a shot join the first pass's windows,
// aligned by the motion vectors. A shot of a textured plane that moves, each frame with its
// own noise: the neighbours lower the error, the motion vectors are what makes them line
// up, the result does not depend on the thread count, and what cannot be used is an error
// naming the frame.
#include "mcdn/nfor.h"
#include "nfor_support.h"

using namespace mcdn;
using namespace nfor_test;

namespace {

struct Shot {
    int width = 64, height = 64;
    float vx = 0, vy = 0;      // motion of the content per frame, pixels (y down)
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

NforOptions shot_options()
{
    NforOptions o;
    o.aovs.preset = "generic";
    o.aovs.overrides["motion"] = { "motion.X", "motion.Y", "motion.Z", "motion.W" };
    return o;
}

/// Frame 0 of the shot denoised with `radius` frames on each side.
OIIO::ImageBuf cross_frame(const Shot& shot, int radius, int nthreads = 0,
                           NforOptions o = shot_options())
{
    std::vector<OIIO::ImageBuf> frames;
    for (int t = -radius; t <= radius; ++t)
        frames.push_back(shot.frame(t));
    for (int k = 1; k <= radius; ++k) {
        o.previous_frames.push_back(&frames[size_t(radius - k)]);
        o.next_frames.push_back(&frames[size_t(radius + k)]);
    }
    OIIO::ImageBuf out = nfor(frames[size_t(radius)], o, {}, nthreads);
    EXPECT_FALSE(out.has_error()) << out.geterror();
    return out;
}

}  // namespace

TEST(NforFrames, NeighboursLowerTheErrorOfAStillShot)
{
    Shot shot;
    const double single = shot.mse(cross_frame(shot, 0), 0);
    const double two = shot.mse(cross_frame(shot, 2), 0);
    EXPECT_LT(two, 0.75 * single) << "single frame " << single << ", ±2 frames " << two;
}

// Motion beyond the window (9 px): unaligned, the neighbours' windows hold other content.
TEST(NforFrames, MotionVectorsAlignAMovingShot)
{
    Shot shot;
    shot.vx = 7.0f;
    shot.vy = -5.0f;
    const double single = shot.mse(cross_frame(shot, 0), 0);
    const double aligned = shot.mse(cross_frame(shot, 2), 0);
    Shot unaligned = shot;
    unaligned.true_motion = false;
    const double without = unaligned.mse(cross_frame(unaligned, 2), 0);
    EXPECT_LT(aligned, 0.75 * single) << "single frame " << single << ", aligned " << aligned;
    EXPECT_LT(aligned, 0.9 * without) << "aligned " << aligned << ", without motion " << without;
}

TEST(NforFrames, OutputIdenticalForOneAndTwoThreads)
{
    Shot shot;
    shot.vx = 1.5f;
    const OIIO::ImageBuf one = cross_frame(shot, 1, 1), two = cross_frame(shot, 1, 2);
    OIIO::ImageBufAlgo::CompareResults r = OIIO::ImageBufAlgo::compare(one, two, 0.0f, 0.0f);
    EXPECT_EQ(r.nfail, 0u);
    EXPECT_TRUE(all_finite(one));
}

TEST(NforFrames, TheOneBufferPathTakesNeighboursToo)
{
    Shot shot;
    NforOptions o = shot_options();
    o.use_halves = false;
    const double single = shot.mse(cross_frame(shot, 0, 0, o), 0);
    const double two = shot.mse(cross_frame(shot, 2, 0, o), 0);
    EXPECT_LT(two, 0.8 * single) << "single frame " << single << ", ±2 frames " << two;
}

TEST(NforFrames, WhatCannotBeUsedIsAnErrorNamingTheFrame)
{
    Shot shot;
    OIIO::ImageBuf centre = shot.frame(0);
    Shot small = shot;
    small.width = 32;
    OIIO::ImageBuf other = small.frame(-1);
    NforOptions o = shot_options();
    o.previous_frames = { &other };
    OIIO::ImageBuf out = nfor(centre, o);
    ASSERT_TRUE(out.has_error());
    EXPECT_NE(out.geterror().find("frame -1"), std::string::npos) << out.geterror();

    OIIO::ImageBuf previous = shot.frame(-1);
    o.previous_frames = { &previous };
    o.aovs.overrides.erase("motion");  // the generic preset has no motion role
    out = nfor(centre, o);
    ASSERT_TRUE(out.has_error());
    EXPECT_NE(out.geterror().find("motion"), std::string::npos) << out.geterror();
}
