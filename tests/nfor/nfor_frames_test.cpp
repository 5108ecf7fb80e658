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

/// Frame 0 of the shot denoised with `radius` frames on each side.
OIIO::ImageBuf cross_frame(const Shot& shot, int radius, int nthreads = 0,
                           NforOptions o = shot_options<NforOptions>())
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
    NforOptions o = shot_options<NforOptions>();
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
    NforOptions o = shot_options<NforOptions>();
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
