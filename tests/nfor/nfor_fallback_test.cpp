// The safety net (lib/src/skip/worse_tiles.h): tiles where NFOR's own MSE estimate is above the
// render's variance are the render. The decision on planes; on the box16 fixture a render
// whose variance files claim a hundredth of its noise (no filter can beat so clean a render,
// by its own estimate) comes out as the render everywhere, and as the filter with the net
// off; on the fixture as rendered nothing falls back.
#include <cmath>

#include "fixtures.h"
#include "mcdn/nfor.h"
#include "skip/worse_tiles.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

constexpr int kTile = kConvergedTileSize;

std::vector<int> channels_of(const ImageBuf& image, Role role)
{
    AovSpec spec;
    spec.preset = "cycles";
    AovSet aovs;
    std::string error;
    EXPECT_TRUE(resolve_aovs(aovs, spec, image.spec(), error)) << error;
    return aovs.channels(role);
}

/// box16 with its colour variance divided by `divisor`.
ImageBuf with_variance_over(const ImageBuf& src, float divisor)
{
    ImageBuf out;
    out.copy(src);
    for (int ch : channels_of(src, Role::ColorVariance))
        for (int y = 0; y < src.spec().height; ++y)
            for (int x = 0; x < src.spec().width; ++x) {
                std::vector<float> px(size_t(out.nchannels()));
                out.getpixel(x, y, 0, px.data(), out.nchannels());
                px[size_t(ch)] /= divisor;
                out.setpixel(x, y, 0, px.data(), out.nchannels());
            }
    return out;
}

NforOptions options(bool fallback)
{
    NforOptions o;
    o.aovs.preset = "cycles";
    o.fallback = fallback;
    o.output_fallback = true;
    o.outliers = NforOptions::Outliers::Off;
    o.skip.enabled = false;  // a render this clean would be converged, and passed through
    return o;
}

}  // namespace

TEST(NforFallback, TilesWhereTheEstimateIsAboveTheVariance)
{
    const int w = 3 * kTile, h = 2 * kTile;
    Plane mse[3], variance[3], result[3];
    for (int c = 0; c < 3; ++c) {
        mse[c] = Plane(w, h, 1.0f);
        variance[c] = Plane(w, h, 2.0f);
        result[c] = Plane(w, h, 0.5f);
    }
    // Tile (1, 0): the filter's estimate above the render's on average, not at every pixel.
    for (int y = 0; y < kTile; ++y)
        for (int x = kTile; x < 2 * kTile; ++x)
            mse[1](x, y) = (x + y) % 2 ? 14.0f : 0.0f;
    // Tile (2, 1) likewise, but converged: it is the render already.
    ConvergedTiles converged;
    converged.width = w;
    converged.height = h;
    converged.tiles_x = 3;
    converged.tiles_y = 2;
    converged.converged = { 0, 0, 0, 0, 0, 1 };
    for (int y = kTile; y < h; ++y)
        for (int x = 2 * kTile; x < w; ++x)
            mse[0](x, y) = 100.0f;
    const ConvergedTiles worse = tiles_worse_than_render(mse, variance, result, converged);
    ASSERT_EQ(worse.count(), 1);
    EXPECT_TRUE(worse.tile(1, 0));
    EXPECT_FALSE(tiles_worse_than_render(mse, variance, result, {}).tile(0, 0));
    EXPECT_TRUE(tiles_worse_than_render(mse, variance, result, {}).tile(2, 1));
}

TEST(NforFallback, AFewPixelsDoNotDecideATileABlotchDoes)
{
    // Two tiles where the filter's estimate is half the render's variance. Tile 0 has 32
    // pixels (3%) of garbage estimates (1e15, a repaired Inf): a plain sum would be theirs.
    // Tile 1 has a blotch over 200 of its pixels (20%), 20 times the variance there.
    const int w = 2 * kTile, h = kTile;
    Plane mse[3], variance[3], result[3];
    for (int c = 0; c < 3; ++c) {
        mse[c] = Plane(w, h, 1.0f);
        variance[c] = Plane(w, h, 2.0f);
        result[c] = Plane(w, h, 0.5f);
    }
    for (int i = 0; i < 32; ++i)
        for (int c = 0; c < 3; ++c)
            mse[c]((i * 7) % kTile, (i * 13) % kTile) = 1e15f;
    for (int y = 0; y < 10; ++y)
        for (int x = kTile; x < kTile + 20; ++x)
            for (int c = 0; c < 3; ++c)
                mse[c](x, y) = 40.0f;
    const ConvergedTiles worse = tiles_worse_than_render(mse, variance, result, {});
    EXPECT_FALSE(worse.tile(0, 0));
    EXPECT_TRUE(worse.tile(1, 0));
}

TEST(NforFallback, TopTrimmedSumDropsTheLargestShare)
{
    std::vector<double> terms(100, 1.0);
    terms[3] = 1e30;
    terms[7] = -1e30;
    terms[9] = 1e20;
    // The 5 largest dropped (the two huge ones among them), the negative one kept.
    EXPECT_EQ(top_trimmed_sum(terms), 94.0 - 1e30);
    std::vector<double> none;
    EXPECT_EQ(top_trimmed_sum(none), 0.0);
}

TEST(NforFallback, OverCleanRenderFallsBackEverywhere)
{
    const ImageBuf clean = with_variance_over(box16(), 100.0f);
    const std::vector<int> color = channels_of(clean, Role::Color);
    const ImageBuf net = nfor(clean, options(true));
    const ImageBuf off = nfor(clean, options(false));
    ASSERT_FALSE(net.has_error()) << net.geterror();
    ASSERT_FALSE(off.has_error()) << off.geterror();
    const int flag = net.spec().channelindex("nfor.fallback");
    ASSERT_GE(flag, 0);
    double changed_off = 0;
    for (int y = 0; y < clean.spec().height; ++y)
        for (int x = 0; x < clean.spec().width; ++x) {
            EXPECT_EQ(net.getchannel(x, y, 0, flag), 1.0f);
            for (int c : color) {
                ASSERT_EQ(net.getchannel(x, y, 0, c), clean.getchannel(x, y, 0, c))
                    << x << "," << y;
                changed_off += std::abs(off.getchannel(x, y, 0, c) - clean.getchannel(x, y, 0, c));
            }
        }
    EXPECT_GT(changed_off, 0.0);
    EXPECT_EQ(net.spec().get_int_attribute("mcdn:nfor_fallback_count"), 4);
}

TEST(NforFallback, RenderAsRenderedKeepsTheFilter)
{
    const ImageBuf in = box16();
    NforOptions o = options(true);
    o.skip.enabled = true;
    EXPECT_TRUE(NforOptions().fallback);  // on by default (docs/accuracy.md)
    const ImageBuf out = nfor(in, o);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    const int flag = out.spec().channelindex("nfor.fallback");
    ASSERT_GE(flag, 0);
    for (int y = 0; y < in.spec().height; ++y)
        for (int x = 0; x < in.spec().width; ++x)
            ASSERT_EQ(out.getchannel(x, y, 0, flag), 0.0f);
    EXPECT_EQ(out.spec().get_int_attribute("mcdn:nfor_fallback_count"), 0);
}
