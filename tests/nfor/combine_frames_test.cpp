// mcdn::combine_frames (mcdn/frames.h): a frame and its aligned neighbours as one render of
// more samples where they agree, this frame's own where they do not.
#include "mcdn/frames.h"
#include "nfor_support.h"

using namespace mcdn;
using namespace nfor_test;

namespace {

struct Frames {
    std::vector<OIIO::ImageBuf> frames;  // t = -radius ... radius
    CombineFramesOptions options = shot_options<CombineFramesOptions>();
    Frames(const Shot& shot, int radius)
    {
        for (int t = -radius; t <= radius; ++t)
            frames.push_back(shot.frame(t));
        for (int k = 1; k <= radius; ++k) {
            options.previous_frames.push_back(&frames[size_t(radius - k)]);
            options.next_frames.push_back(&frames[size_t(radius + k)]);
        }
    }
    const OIIO::ImageBuf& centre() const { return frames[frames.size() / 2]; }
    /// Each frame as Cycles writes it: the colour, the albedo and the vectors; no variance
    /// and no halves.
    void without_variance()
    {
        for (OIIO::ImageBuf& f : frames)
            f = OIIO::ImageBufAlgo::channels(f, 10, { 0, 1, 2, 3, 4, 5, 24, 25, 26, 27 });
    }
};

double mean_channel(const OIIO::ImageBuf& img, int channel)
{
    double sum = 0;
    for (int y = 8; y < img.spec().height - 8; ++y)
        for (int x = 8; x < img.spec().width - 8; ++x)
            sum += img.getchannel(x, y, 0, channel);
    return sum / ((img.spec().height - 16) * (img.spec().width - 16));
}

}  // namespace

// A moving shot aligned by its vectors: five frames' samples, a fifth of the error and of
// the variance channel. Without a variance (Cycles writes none) the frames' agreement weighs
// them, with as much of the gain.
TEST(CombineFrames, AMovingShotBecomesARenderOfMoreSamples)
{
    Shot shot;
    shot.vx = 2.0f;
    shot.vy = -1.0f;
    for (bool variance : { true, false }) {
        Frames f(shot, 2);
        if (!variance)
            f.without_variance();
        OIIO::ImageBuf out = combine_frames(f.centre(), f.options);
        ASSERT_FALSE(out.has_error()) << out.geterror();
        const double before = shot.mse(f.centre(), 0), after = shot.mse(out, 0);
        EXPECT_LT(after, 0.3 * before) << before << " -> " << after << ", variance " << variance;
        EXPECT_TRUE(all_finite(out));
        const int variance_r = 6;  // variance.R in the generic layout
        if (variance)
            EXPECT_LT(mean_channel(out, variance_r), 0.3 * mean_channel(f.centre(), variance_r));
    }
}

// Where the neighbours show something else (wrong motion vectors: they say still, the
// picture moves 6 px a frame) they get no weight: the frame stays near its own error, with
// the variance or without.
TEST(CombineFrames, NeighboursThatDisagreeAreLeftOut)
{
    Shot shot;
    shot.vx = 6.0f;
    shot.true_motion = false;
    for (bool variance : { true, false }) {
        Frames f(shot, 2);
        if (!variance)
            f.without_variance();
        OIIO::ImageBuf out = combine_frames(f.centre(), f.options);
        ASSERT_FALSE(out.has_error()) << out.geterror();
        const double before = shot.mse(f.centre(), 0), after = shot.mse(out, 0);
        EXPECT_LT(after, 1.2 * before) << before << " -> " << after << ", variance " << variance;
    }
}

// RenderMan's backward and forward (motionBack, motionFore: raster space, y down) are its
// motion role: the same shot named as RenderMan writes it combines exactly as Blender's.
TEST(CombineFrames, RenderMansBackwardAndForwardAreItsMotion)
{
    Shot shot;
    shot.vx = 2.0f;
    shot.vy = -1.0f;
    Frames f(shot, 1);
    const std::vector<std::string> names = { "Ci.r",     "Ci.g",       "Ci.b",       "mse.r",
                                             "mse.g",    "mse.b",      "albedo.r",   "albedo.g",
                                             "albedo.b", "backward.x", "backward.y", "forward.x",
                                             "forward.y" };
    std::vector<OIIO::ImageBuf> rman;
    for (const OIIO::ImageBuf& frame : f.frames)
        rman.push_back(mcdn_test::make_image(
            shot.width, shot.height, names, [&](int x, int y, int c) -> float {
                // R,G,B; variance.R,G,B; albedo.R,G,B; then the motion: Blender's
                // (X, -Y) to the previous frame and (-Z, W) to the next.
                static const int from[] = { 0, 1, 2, 6, 7, 8, 3, 4, 5, 24, 25, 26, 27 };
                static const float sign[] = { 1, 1, 1, 1, 1, 1, 1, 1, 1, 1, -1, -1, 1 };
                return sign[c] * frame.getchannel(x, y, 0, from[c]);
            }));
    CombineFramesOptions o;
    o.aovs.preset = "renderman";
    o.previous_frames = { &rman[0] };
    o.next_frames = { &rman[2] };
    const OIIO::ImageBuf out = combine_frames(rman[1], o);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    // The same frames with Blender's names, without their halves (RenderMan writes none).
    for (OIIO::ImageBuf& frame : f.frames)
        frame = OIIO::ImageBufAlgo::channels(
            frame, 16, { 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 24, 25, 26, 27 });
    const OIIO::ImageBuf blender = combine_frames(f.centre(), f.options);
    ASSERT_FALSE(blender.has_error()) << blender.geterror();
    EXPECT_LT(shot.mse(out, 0), 0.6 * shot.mse(rman[1], 0));
    for (int y = 0; y < shot.height; ++y)
        for (int x = 0; x < shot.width; ++x)
            for (int c = 0; c < 3; ++c)
                ASSERT_EQ(out.getchannel(x, y, 0, c), blender.getchannel(x, y, 0, c))
                    << x << "," << y;
}

TEST(CombineFrames, OutputIdenticalForOneAndTwoThreads)
{
    Shot shot;
    shot.vx = 1.5f;
    Frames f(shot, 1);
    for (bool variance : { true, false }) {
        if (!variance)
            f.without_variance();
        const OIIO::ImageBuf one = combine_frames(f.centre(), f.options, {}, 1);
        const OIIO::ImageBuf two = combine_frames(f.centre(), f.options, {}, 2);
        EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, two, 0.0f, 0.0f).nfail, 0u);
    }
}

// The denoiser sees the combined frames; its result keeps the render's own variance and
// halves (what SURE and the mix read of the render), its denoised colour.
TEST(CombineFrames, ADenoiserOfTheFramesKeepsTheRendersOwnChannels)
{
    Shot shot;
    Frames f(shot, 1);
    OIIO::ImageBuf seen;
    OIIO::ImageBuf out;
    ASSERT_TRUE(denoise_with_frames(out, f.centre(), f.options,
                                    [&](OIIO::ImageBuf& d, const OIIO::ImageBuf& s) {
                                        seen.copy(s);
                                        d.copy(s);
                                        return true;
                                    }))
        << out.geterror();
    const int r = 0, variance_r = 6, half_a_r = 12;
    EXPECT_LT(shot.mse(seen, 0), 0.6 * shot.mse(f.centre(), 0)) << "the denoiser saw 3 frames";
    EXPECT_EQ(out.getchannel(20, 20, 0, r), seen.getchannel(20, 20, 0, r));
    for (int c : { variance_r, half_a_r })
        EXPECT_EQ(out.getchannel(20, 20, 0, c), f.centre().getchannel(20, 20, 0, c));
}

TEST(CombineFrames, WhatCannotBeUsedIsAnErrorNamingTheFrame)
{
    Shot shot;
    Frames f(shot, 1);
    CombineFramesOptions o = f.options;
    o.aovs.overrides.erase("motion");
    OIIO::ImageBuf out = combine_frames(f.centre(), o);
    ASSERT_TRUE(out.has_error());
    EXPECT_NE(out.geterror().find("motion"), std::string::npos) << out.geterror();

    OIIO::ImageBuf fewer = OIIO::ImageBufAlgo::channels(f.frames[0], 3, { 0, 1, 2 });
    o = f.options;
    o.previous_frames = { &fewer };
    out = combine_frames(f.centre(), o);
    ASSERT_TRUE(out.has_error());
    EXPECT_NE(out.geterror().find("frame -1"), std::string::npos) << out.geterror();
}
