// Heavy-tailed samples before the KPCN's kernels (CnnOptions::outliers,
// lib/src/outliers/outliers.h): a firefly planted in the box16 render, as one sample of a
// caustic path would land. Left in, the kernels spread it over its neighbours; taken out, the
// neighbourhood comes out as without it and the excess is gone. Renders without such samples
// come out exactly as with the detection off, whole or in tiles.
#include <OpenImageIO/imagebufalgo.h>

#include "firefly.h"
#include "fixtures.h"
#include "mcdn/cnn.h"
#include "partition.h"
#include "same_pixels.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

constexpr int kX = 30, kY = 34;  // inside box16 (64×64), away from its edges
constexpr int kReach = 8;        // around the firefly: the kernels' reach and more

CnnOptions options(CnnOptions::Outliers mode)
{
    CnnOptions o;
    o.aovs.preset = "cycles";
    o.outliers = mode;
    return o;
}

}  // namespace

TEST(CnnOutliers, AFireflyIsNotSpreadOverItsNeighbours)
{
    const ImageBuf clean = box16();
    AovSpec spec;
    spec.preset = "cycles";
    const ImageBuf fire = with_firefly(clean, spec, kX, kY, 500.0f);
    const std::vector<int> color = color_channels(clean, spec).mean;

    const ImageBuf clean_out = cnn(clean, options(CnnOptions::Outliers::Drop));
    const ImageBuf drop = cnn(fire, options(CnnOptions::Outliers::Drop));
    const ImageBuf off = cnn(fire, options(CnnOptions::Outliers::Off));
    ASSERT_FALSE(drop.has_error()) << drop.geterror();
    ASSERT_FALSE(off.has_error()) << off.geterror();
    // Taken out: the neighbours are within a few percent of the render without the firefly
    // (its median stands in for the pixel's own value); left in, the kernels spread it.
    EXPECT_LT(largest_change_around(drop, clean_out, color, kX, kY, kReach), 0.03f);
    EXPECT_GT(largest_change_around(off, clean_out, color, kX, kY, kReach), 0.5f);
    for (int c : color) {  // and the excess is gone from the pixel too
        const float base = clean_out.getchannel(kX, kY, 0, c);
        EXPECT_NEAR(drop.getchannel(kX, kY, 0, c), base, 0.1f * (base + 0.05f));
    }
}

TEST(CnnOutliers, RendersWithoutHeavyTailsComeOutAsWithTheDetectionOff)
{
    for (const char* name : { "box16", "cornell20" }) {
        const bool box = std::string(name) == "box16";
        const ImageBuf src = box ? box16() : cornell20();
        CnnOptions drop = options(CnnOptions::Outliers::Drop), off = drop;
        off.outliers = CnnOptions::Outliers::Off;
        drop.aovs.preset = off.aovs.preset = box ? "cycles" : "tungsten";
        EXPECT_TRUE(same_pixels(cnn(src, drop), cnn(src, off))) << name;
    }
}

TEST(CnnOutliers, InTilesAsOnTheWholeFrame)
{
    // The firefly a pixel from a tile's edge: every tile sees the same input.
    AovSpec spec;
    spec.preset = "cycles";
    const ImageBuf src = with_firefly(box16(), spec, 32, 33, 500.0f);
    CnnOptions whole = options(CnnOptions::Outliers::Drop), tiled = whole;
    whole.tile_size = 256;
    tiled.tile_size = 32;
    const ImageBuf a = cnn(src, whole, {}, 2), b = cnn(src, tiled, {}, 2);
    EXPECT_TRUE(same_pixels(a, b)) << "largest difference " << max_difference(a, b);
}

TEST(CnnOutliers, LightGroupsStillAddUpToTheBeauty)
{
    AovSpec cycles;
    cycles.preset = "cycles";
    Partition p = add_light_groups(with_firefly(box16(), cycles, kX, kY, 500.0f), "cycles", false);
    CnnOptions o = options(CnnOptions::Outliers::Drop);
    o.aovs = p.spec;
    const ImageBuf out = cnn(p.image, o);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    EXPECT_LT(partition_error(out, p), 1e-4);
    // The key light, too, lost its share of the firefly around it.
    const ImageBuf off = [&] {
        CnnOptions left_in = o;
        left_in.outliers = CnnOptions::Outliers::Off;
        return cnn(p.image, left_in);
    }();
    EXPECT_LT(out.getchannel(kX + 1, kY, 0, p.key[0]), off.getchannel(kX + 1, kY, 0, p.key[0]));
}
