// KPCN's inputs made per network tile (lib/src/cnn/branch_inputs.cpp) are the whole frame's,
// bit for bit: windows inside the frame, at its edges, and past them (run_tiled's extension
// to the alignment repeats the last row and column).
#include <gtest/gtest.h>

#include <OpenImageIO/filesystem.h>

#include "cnn/cnn_steps.h"
#include "fixtures.h"

using namespace mcdn;

namespace {

/// Pixel (x, y) of the whole-frame tensor with run_tiled's extension past the frame.
const float* extended(const nn::Tensor& whole, int x, int y)
{
    return whole.pixel(std::min(y, whole.height - 1), std::min(x, whole.width - 1));
}

}  // namespace

TEST(CnnTileInputs, WindowsEqualTheWholeFrame)
{
    const ImageBuf src = mcdn_test::read_render(
        mcdn_test::test_data("generated/0000_interior/0000_interior_0016spp"));
    AovSet aovs;
    std::string error;
    ASSERT_TRUE(resolve_aovs(aovs, AovSpec {}, src.spec(), error)) << error;
    const int w = src.spec().width, h = src.spec().height;

    kpcn::RawPlanes whole_raw;
    ASSERT_TRUE(kpcn::read_raw_planes(whole_raw, src, aovs, error)) << error;
    ASSERT_TRUE(whole_raw.split);
    // The range read in bands is the whole plane's.
    const kpcn::DepthRange range = kpcn::depth_range(src, aovs);
    const kpcn::DepthRange from_plane = kpcn::depth_range(whole_raw.depth);
    EXPECT_GT(range.span, 0.0f);
    EXPECT_EQ(range.lo, from_plane.lo);
    EXPECT_EQ(range.span, from_plane.span);
    kpcn::scale_depth(whole_raw);

    for (kpcn::Branch branch : { kpcn::Branch::diffuse, kpcn::Branch::specular }) {
        nn::Tensor features, image;
        kpcn::branch_inputs(whole_raw, branch, features, image);
        // Inside, at the left/top edge, across the right/bottom edge and past it, one pixel.
        for (Rect window : { Rect { 4, 8, 20, 16 }, Rect { 0, 0, 12, 32 },
                             Rect { 16, 12, w + 3, h + 5 }, Rect { w - 1, h - 1, w, h } }) {
            kpcn::RawPlanes raw;
            ASSERT_TRUE(
                kpcn::read_raw_planes(raw, src, aovs, error, kpcn::inputs_rect(window, w, h)))
                << error;
            kpcn::scale_depth(raw, range);
            nn::Tensor f, i;
            kpcn::branch_inputs(raw, branch, window, f, i);
            ASSERT_EQ(f.height, window.y1 - window.y0);
            ASSERT_EQ(f.width, window.x1 - window.x0);
            int differ = 0;
            for (int y = window.y0; y < window.y1; ++y)
                for (int x = window.x0; x < window.x1; ++x) {
                    const float* a = f.pixel(y - window.y0, x - window.x0);
                    const float* b = extended(features, x, y);
                    for (int c = 0; c < kpcn::kInputChannels; ++c)
                        differ += a[c] != b[c];
                    for (int c = 0; c < 3; ++c)
                        differ +=
                            i.pixel(y - window.y0, x - window.x0)[c] != extended(image, x, y)[c];
                }
            EXPECT_EQ(differ, 0) << "window " << window.x0 << "," << window.y0 << " - " << window.x1
                                 << "," << window.y1;
        }
    }
}

TEST(CnnTileInputs, DepthRangeInBandsIsTheWholePlanes)
{
    // The shared box render (256 rows) is taller than a band (64): the range is gathered
    // over several.
    const std::string box = std::string(MCDN_SHARED_DATA) + "/box/box_0016spp";
    if (!OIIO::Filesystem::exists(box + ".exr"))
        GTEST_SKIP() << box << ".exr absent (../shared/data)";
    const ImageBuf src = mcdn_test::read_render(box);
    AovSet aovs;
    std::string error;
    ASSERT_TRUE(resolve_aovs(aovs, AovSpec {}, src.spec(), error)) << error;
    ASSERT_GT(src.spec().height, 64);
    kpcn::RawPlanes raw;
    ASSERT_TRUE(kpcn::read_raw_planes(raw, src, aovs, error)) << error;
    const kpcn::DepthRange bands = kpcn::depth_range(src, aovs);
    const kpcn::DepthRange whole = kpcn::depth_range(raw.depth);
    EXPECT_GT(whole.span, 0.0f);
    EXPECT_EQ(bands.lo, whole.lo);
    EXPECT_EQ(bands.span, whole.span);
}
