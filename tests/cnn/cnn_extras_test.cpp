// Extra AOVs (light groups) through the beauty's KPCN kernels add up to the denoised beauty,
// with the diffuse/specular split (Cycles passes) and without it (Tungsten buffers).
#include <OpenImageIO/imagebufalgo.h>

#include "fixtures.h"
#include "mcdn/cnn.h"
#include "mcdn/io.h"
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

        // In place (the chain's own band): the same light groups.
        o.denoise_extras = true;
        ImageBuf in_place = p.image.copy(OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(cnn(in_place, in_place, o)) << in_place.geterror();
        EXPECT_EQ(OIIO::ImageBufAlgo::compare(in_place, out, 0, 0).maxerror, 0.0) << preset;
    }
}

TEST(CnnExtras, ReadingTheRolesOnlyDenoisesAsReadingEveryChannel)
{
    // A Blender file with transmission passes (no role: the CNN reads them by name beside
    // DiffCol for its specular variance): mcdntool reads only the roles' faces unless a
    // command names channels, and both must give the same CNN result.
    const std::string base = test_data("generated/0000_interior/0000_interior_0016spp");
    const std::vector<InputFile> files = { { base + ".exr", InputKind::Mean },
                                           { base + "_var.exr", InputKind::Variance } };
    ImageBuf denoised[2];
    for (bool only_roles : { false, true }) {
        InputSelection selection;
        selection.only_roles = only_roles;
        selection.halves = false;
        selection.aovs.preset = "cycles";
        ImageBuf merged;
        ASSERT_TRUE(read_inputs(merged, files, selection)) << merged.geterror();
        ASSERT_GE(merged.spec().channelindex("variance.ViewLayer.TransDir.R"), 0) << only_roles;
        CnnOptions o;
        o.aovs.preset = "cycles";
        denoised[only_roles] = cnn(merged, o);
        ASSERT_FALSE(denoised[only_roles].has_error()) << denoised[only_roles].geterror();
    }
    const int r = denoised[0].spec().channelindex("ViewLayer.Combined.R");
    ASSERT_GE(r, 0);
    for (int y = 0; y < denoised[0].spec().height; ++y)
        for (int x = 0; x < denoised[0].spec().width; ++x)
            for (int c = 0; c < 3; ++c)
                ASSERT_EQ(denoised[0].getchannel(x, y, 0, r + c),
                          denoised[1].getchannel(x, y, 0,
                                                 denoised[1].spec().channelindex(
                                                     denoised[0].spec().channelnames[r + c])))
                    << x << "," << y;
}
