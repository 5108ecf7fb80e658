// Extra AOVs (light groups) through the beauty's KPCN kernels add up to the denoised beauty,
// with the diffuse/specular split (Cycles passes) and without it (Tungsten buffers).
#include "fixtures.h"
#include "mcdn/cnn.h"
#include "partition.h"

using namespace mcdn;
using namespace mcdn_test;

TEST(CnnExtras, LightGroupsAddUpToTheDenoisedBeauty)
{
    for (const char* preset : { "cycles", "tungsten" }) {
        Partition p = add_light_groups(preset == std::string("cycles") ? box16() : cornell20(),
                                       preset, false);
        CnnOptions o;
        o.aovs = p.spec;
        ImageBuf out = cnn(p.image, o);
        ASSERT_FALSE(out.has_error()) << out.geterror();
        EXPECT_LT(partition_error(out, p), 1e-4) << preset;
        // Denoised, not copied: the key light moved.
        double moved = 0;
        for (int c = 0; c < 3; ++c)
            for (int y = 0; y < out.spec().height; ++y)
                for (int x = 0; x < out.spec().width; ++x)
                    moved += std::abs(out.getchannel(x, y, 0, p.key[c])
                                      - p.image.getchannel(x, y, 0, p.key[c]));
        EXPECT_GT(moved / (3.0 * out.spec().image_pixels()), 1e-3) << preset;

        // The beauty is the same as without extras.
        o.denoise_extras = false;
        ImageBuf alone = cnn(p.image, o);
        for (int c = 0; c < 3; ++c) {
            const float v = alone.getchannel(7, 9, 0, p.beauty[c]);
            EXPECT_NEAR(out.getchannel(7, 9, 0, p.beauty[c]), v, 1e-5f * std::abs(v) + 1e-7f);
        }
        EXPECT_EQ(alone.getchannel(7, 9, 0, p.key[0]), p.image.getchannel(7, 9, 0, p.key[0]));
    }
}
