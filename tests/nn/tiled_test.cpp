// Tiled inference equals the whole-image run: same pooling grid, same border padding,
// a halo as wide as the receptive field.
#include <array>

#include "nn_test_util.h"

using namespace nn_test;

namespace {

/// A small UNet with a kernel-prediction head: 2 poolings (alignment 4).
Net small_unet()
{
    Net net("unet");
    Value x = net.input("features", 7);
    Value e1 = net.conv(x, "enc1", 12, 3);
    Value e2 = net.conv(net.max_pool2(e1), "enc2", 16, 3);
    Value b = net.conv(net.max_pool2(e2), "bottleneck", 16, 3);
    Value d2 = net.conv(net.concat({ net.upsample2(b), e2 }), "dec2", 16, 3);
    Value d1 = net.conv(net.concat({ net.upsample2(d2), e1 }), "dec1", 12, 3);
    net.output("denoised", net.apply_kernel(net.conv(d1, "kernel", 9, 3, Activation::none),
                                            net.slice(x, 0, 3), 3));
    net.output("features", d1);
    return net;
}

TEST(NnTiled, ReceptiveFieldAndAlignment)
{
    Net net = small_unet();
    EXPECT_EQ(net.alignment(), 4);
    // enc1 1 + pool 1 + enc2 2 + pool 2 + bottleneck 4 + up 2 + dec2 2 + up 1 + dec1 1
    // + kernel conv 1 = 17; the image path is shorter.
    EXPECT_EQ(net.receptive_radius(), 17);
}

TEST(NnTiled, EqualsWholeImageRun)
{
    Net net = small_unet();
    std::string error;
    ASSERT_TRUE(net.load(random_weights(net, 3), error)) << error;
    const Tensor input = random_tensor(72, 100, 7, 4);  // aligned: run() accepts it too
    std::vector<Tensor> whole, tiled;
    ASSERT_TRUE(net.run({ input }, whole, error)) << error;
    for (int tile : { 16, 1000 }) {
        TileOptions options;
        options.tile_size = tile;
        ASSERT_TRUE(run_tiled(net, { input }, tiled, error, options)) << error;
        ASSERT_EQ(tiled.size(), 2u);
        for (int o = 0; o < 2; ++o)
            EXPECT_LT(relative_error(tiled[o], whole[o]), 1e-6)
                << "tile " << tile << " output " << o;
    }
}

TEST(NnTiled, AnySizeIsExtendedAndCropped)
{
    Net net = small_unet();
    std::string error;
    ASSERT_TRUE(net.load(random_weights(net, 5), error)) << error;
    const Tensor input = random_tensor(37, 51, 7, 6);  // not multiples of 4
    std::vector<Tensor> one_tile, small_tiles;
    TileOptions options;
    options.tile_size = 1 << 20;
    ASSERT_TRUE(run_tiled(net, { input }, one_tile, error, options)) << error;
    EXPECT_EQ(one_tile[0].height, 37);
    EXPECT_EQ(one_tile[0].width, 51);
    options.tile_size = 12;
    ASSERT_TRUE(run_tiled(net, { input }, small_tiles, error, options)) << error;
    EXPECT_LT(relative_error(small_tiles[0], one_tile[0]), 1e-6);
    options.backend = Backend::reference;
    ASSERT_TRUE(run_tiled(net, { input }, small_tiles, error, options)) << error;
    EXPECT_LT(relative_error(small_tiles[0], one_tile[0]), 1e-5);
}

}  // namespace

namespace {

int64_t area(const mcdn::Rect& r)
{
    return int64_t(r.x1 - r.x0) * (r.y1 - r.y0);
}

}  // namespace

// TileOptions::balanced: the cores tile the extended image exactly once, no window holds more
// than a square tile's, the windows add up to no more than the square grid's, and the output
// is the whole-image run's.
TEST(NnTiled, BalancedGridsComputeLessHaloInTheSameMemory)
{
    Net net = small_unet();  // halo 20 (17 rounded up to the alignment 4)
    std::string error;
    for (const auto& [height, width, tile] : std::vector<std::array<int, 3>> { { 1080, 1920, 1024 },
                                                                               { 1080, 1920, 768 },
                                                                               { 37, 51, 12 },
                                                                               { 4320, 7680, 1000 },
                                                                               { 8, 8, 64 } }) {
        TileOptions options;
        options.tile_size = tile;
        std::vector<Tile> square, balanced;
        ASSERT_TRUE(plan_tiles(net, height, width, options, square, error)) << error;
        options.balanced = true;
        ASSERT_TRUE(plan_tiles(net, height, width, options, balanced, error)) << error;
        const int padded_h = (height + 3) / 4 * 4, padded_w = (width + 3) / 4 * 4;
        const int side = (tile + 3) / 4 * 4 + 2 * 20;
        std::vector<int> covered(size_t(padded_h) * padded_w, 0);
        int64_t square_area = 0, balanced_area = 0;
        for (const Tile& t : square)
            square_area += area(t.window);
        for (const Tile& t : balanced) {
            balanced_area += area(t.window);
            EXPECT_LE(area(t.window), int64_t(side) * side) << width << "x" << height;
            EXPECT_EQ(t.core.x0 % 4, 0);
            EXPECT_EQ(t.core.y0 % 4, 0);
            for (int y = t.core.y0; y < t.core.y1; ++y)
                for (int x = t.core.x0; x < t.core.x1; ++x)
                    ++covered[size_t(y) * padded_w + x];
        }
        EXPECT_TRUE(std::all_of(covered.begin(), covered.end(), [](int n) { return n == 1; }))
            << width << "x" << height;
        EXPECT_LE(balanced_area, square_area) << width << "x" << height;
        if (tile == 1024) {
            EXPECT_EQ(balanced.size(), 2u);  // two windows of 1004 x 1080, where squares make 4
        }
    }
    ASSERT_TRUE(net.load(random_weights(net, 7), error)) << error;
    const Tensor input = random_tensor(90, 130, 7, 8);
    std::vector<Tensor> whole, tiled;
    TileOptions options;
    options.tile_size = 1 << 20;
    ASSERT_TRUE(run_tiled(net, { input }, whole, error, options)) << error;
    options.tile_size = 24;
    options.balanced = true;
    ASSERT_TRUE(run_tiled(net, { input }, tiled, error, options)) << error;
    for (int o = 0; o < 2; ++o)
        EXPECT_LT(relative_error(tiled[o], whole[o]), 1e-6) << "output " << o;
}
