// Tiled inference equals the whole-image run: same pooling grid, same border padding,
// a halo as wide as the receptive field.
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
