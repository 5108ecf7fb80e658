// Our OpenColorIO config loads, validates, and its transforms are the published matrices.
#include <array>

#include <OpenColorIO/OpenColorIO.h>

#include "mcdn_test.h"

namespace OCIO = OCIO_NAMESPACE;

namespace {

OCIO::ConstConfigRcPtr config()
{
    return OCIO::Config::CreateFromFile(MCDN_SOURCE_DIR "/ocio/config.ocio");
}

std::array<float, 3> apply(const char* from, const char* to, std::array<float, 3> rgb)
{
    config()->getProcessor(from, to)->getDefaultCPUProcessor()->applyRGB(rgb.data());
    return rgb;
}

}  // namespace

TEST(OcioConfig, LoadsAndValidates)
{
    auto c = config();
    EXPECT_NO_THROW(c->validate());
    EXPECT_STREQ(c->getColorSpace(OCIO::ROLE_SCENE_LINEAR)->getName(), "lin_rec709");
    EXPECT_TRUE(c->getColorSpace(OCIO::ROLE_DATA)->isData());
    // Blender and OIIO label scene-linear files "Linear": an alias of the working space.
    EXPECT_STREQ(c->getColorSpace("Linear")->getName(), "lin_rec709");
}

TEST(OcioConfig, Rec709ToAcescgIsTheBradfordMatrixAndRoundTrips)
{
    auto red = apply("lin_rec709", "acescg", { 1, 0, 0 });
    EXPECT_NEAR(red[0], 0.6131, 1e-4);
    EXPECT_NEAR(red[1], 0.0702, 1e-4);
    EXPECT_NEAR(red[2], 0.0206, 1e-4);
    auto back = apply("acescg", "lin_rec709", red);
    EXPECT_NEAR(back[0], 1.0, 1e-5);
    EXPECT_NEAR(back[1], 0.0, 1e-5);
    auto white = apply("lin_rec709", "aces2065_1", { 1, 1, 1 });
    for (float v : white)
        EXPECT_NEAR(v, 1.0, 1e-3);  // white stays white across the adapted spaces
}

TEST(OcioConfig, SrgbDisplayEncodesMiddleGrey)
{
    auto grey = apply("lin_rec709", "srgb_display", { 0.18f, 0.18f, 0.18f });
    EXPECT_NEAR(grey[0], 0.4614, 1e-3);
}
