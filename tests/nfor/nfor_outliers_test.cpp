// Heavy-tailed samples (lib/src/outliers/outliers.h): a firefly planted in the box16 render, as
// one sample of a caustic path would land — in one half buffer, its mean and a variance to
// match. NFOR keeps it out of the regressions: the neighbourhood is what it is without it,
// and the excess is back at the pixel (keep) or gone (drop). Renders without such samples
// come out exactly as with the detection off.
#include <algorithm>
#include <cmath>

#include <OpenImageIO/imagebufalgo.h>

#include "firefly.h"
#include "fixtures.h"
#include "mcdn/nfor.h"
#include "partition.h"
#include "same_pixels.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

constexpr int kX = 30, kY = 34;  // inside box16 (64×64), away from its edges

NforOptions options(NforOptions::Outliers mode)
{
    NforOptions o;
    o.aovs.preset = "cycles";
    o.outliers = mode;
    return o;
}

/// NFOR's window reach around a pixel (37×37).
constexpr int kNforReach = 18;

}  // namespace

TEST(NforOutliers, AFireflyStaysAtItsPixelAndItsNeighboursAsWithout)
{
    const ImageBuf clean = box16();
    AovSpec spec;
    spec.preset = "cycles";
    float excess[3];
    const ImageBuf fire = with_firefly(clean, spec, kX, kY, 500.0f, excess);
    const std::vector<int> color = color_channels(clean, spec).mean;

    const ImageBuf clean_out = nfor(clean, options(NforOptions::Outliers::Keep));
    const ImageBuf keep = nfor(fire, options(NforOptions::Outliers::Keep));
    const ImageBuf drop = nfor(fire, options(NforOptions::Outliers::Drop));
    const ImageBuf off = nfor(fire, options(NforOptions::Outliers::Off));
    ASSERT_FALSE(keep.has_error()) << keep.geterror();

    // Kept out: the neighbours are within a few percent of the render without the firefly
    // (its median stands in for the pixel's own value); left in, the regression spreads it
    // over them many times over.
    EXPECT_LT(largest_change_around(keep, clean_out, color, kX, kY, kNforReach), 0.1f);
    EXPECT_LT(largest_change_around(drop, clean_out, color, kX, kY, kNforReach), 0.1f);
    EXPECT_GT(largest_change_around(off, clean_out, color, kX, kY, kNforReach), 1.0f);
    for (int c = 0; c < 3; ++c) {
        const float base = clean_out.getchannel(kX, kY, 0, color[c]);
        // keep: the whole excess is back at the pixel; drop: none of it.
        EXPECT_NEAR(keep.getchannel(kX, kY, 0, color[c]) - base, excess[c], 0.01f * excess[c]);
        EXPECT_NEAR(drop.getchannel(kX, kY, 0, color[c]), base, 0.1f * (base + 0.05f));
    }
}

TEST(NforOutliers, RendersWithoutHeavyTailsComeOutAsWithTheDetectionOff)
{
    // box16 at 16 spp has fireflies of a few times their neighbours: the regression's own
    // business, not outliers. Nor are cornell20's dim corner pixels beside black ones.
    for (const char* name : { "box16", "cornell20" }) {
        const bool box = std::string(name) == "box16";
        const ImageBuf src = box ? box16() : cornell20();
        NforOptions keep = options(NforOptions::Outliers::Keep), off = keep;
        off.outliers = NforOptions::Outliers::Off;
        keep.aovs.preset = off.aovs.preset = box ? "cycles" : "tungsten";
        EXPECT_TRUE(same_pixels(nfor(src, keep), nfor(src, off))) << name;
    }
}

TEST(NforOutliers, ASparselySampledDimLightIsNotAnOutlier)
{
    // A dim light that few paths reach, at low sample counts: most pixels drew nothing
    // (black, or nearly, with no variance to speak of), and every other pixel of every other
    // row one sample in one half. Each such pixel towers over its neighbourhood's median,
    // but the light is those samples: the neighbours' mean holds it, and NFOR averages them.
    for (const float background : { 0.0f, 1e-4f }) {
        ImageBuf src;
        src.copy(box16());
        AovSpec spec;
        spec.preset = "cycles";
        const ColorChannels ch = color_channels(src, spec);
        std::vector<float> px(size_t(src.nchannels()));
        for (int y = 8; y < 40; ++y)
            for (int x = 8; x < 40; ++x) {
                src.getpixel(x, y, 0, px.data(), src.nchannels());
                const bool sample = x % 2 == 0 && y % 2 == 0;
                for (int c = 0; c < 3; ++c) {
                    const float excess = sample ? 2.0f : 0.0f;
                    px[size_t(ch.mean[c])] = background + excess;
                    px[size_t(ch.half_a[c])] = background + 2.0f * excess;
                    px[size_t(ch.half_b[c])] = background;
                    px[size_t(ch.variance[c])] = background * background + excess * excess;
                }
                src.setpixel(x, y, 0, px.data(), src.nchannels());
            }
        const ImageBuf keep = nfor(src, options(NforOptions::Outliers::Keep));
        const ImageBuf off = nfor(src, options(NforOptions::Outliers::Off));
        ASSERT_FALSE(keep.has_error()) << keep.geterror();
        EXPECT_TRUE(same_pixels(keep, off)) << "background " << background;
    }
}

TEST(NforOutliers, InBandsAsOnTheWholeFrame)
{
    // The firefly sits a few rows from a band's edge: the halo covers its detection too.
    AovSpec spec;
    spec.preset = "cycles";
    const ImageBuf src = with_firefly(tall_box16(), spec, kX, 64 + 2, 500.0f);
    NforOptions whole = options(NforOptions::Outliers::Keep), banded = whole;
    whole.band_pixels = 0;
    banded.band_pixels = int64_t(src.spec().width) * 64;
    const ImageBuf a = nfor(src, whole, {}, 2), b = nfor(src, banded, {}, 2);
    EXPECT_TRUE(same_pixels(a, b)) << "largest difference " << max_difference(a, b);
}

TEST(NforOutliers, LightGroupsStillAddUpToTheBeauty)
{
    AovSpec cycles;
    cycles.preset = "cycles";
    float excess[3];
    Partition p =
        add_light_groups(with_firefly(box16(), cycles, kX, kY, 500.0f, excess), "cycles", true);
    for (NforOptions::Outliers mode :
         { NforOptions::Outliers::Keep, NforOptions::Outliers::Drop }) {
        NforOptions o = options(mode);
        o.aovs = p.spec;
        const ImageBuf out = nfor(p.image, o);
        ASSERT_FALSE(out.has_error()) << out.geterror();
        for (int y = 0; y < out.spec().height; ++y)
            for (int x = 0; x < out.spec().width; ++x)
                for (int c = 0; c < 3; ++c) {
                    const float beauty = out.getchannel(x, y, 0, p.beauty[c]);
                    const float sum =
                        out.getchannel(x, y, 0, p.key[c]) + out.getchannel(x, y, 0, p.fill[c]);
                    ASSERT_NEAR(sum, beauty, 1e-4f * (std::fabs(beauty) + 1.0f))
                        << "at " << x << "," << y << " channel " << c;
                }
        // Keep: the beauty has the excess back, and so do its groups between them.
        if (mode == NforOptions::Outliers::Keep) {
            EXPECT_GT(out.getchannel(kX, kY, 0, p.beauty[0]), 0.5f * excess[0]);
        }
    }
}
