// mcdn::prefilter: cross-filtered features are cleaner, constants stay, the op keeps every
// channel, marks its output, survives NaN feature variance, and is thread independent.
#include <cstring>

#include "../nfor/nfor_support.h"
#include "mcdn/prefilter.h"

using namespace mcdn;
using namespace nfor_test;

namespace {

// Generic layout with noisy features: the colour is irrelevant here.
OIIO::ImageBuf noisy_features(float sigma)
{
    return mcdn_test::make_image(64, 64, generic_channels(), [&](int x, int y, int ch) {
        int face = ch / 6, c = ch % 6;
        float clean = c < 3 ? 0.5f : (x < 32 ? 0.2f : 0.8f) + 0.1f * (c - 3);  // an edge
        float a = clean + sigma * gauss(x, y, 2 * c), b = clean + sigma * gauss(x, y, 2 * c + 1);
        switch (face) {
        case 0: return 0.5f * (a + b);
        case 1: return 0.5f * sigma * sigma;
        case 2: return a;
        default: return b;
        }
    });
}

double feature_mse(const OIIO::ImageBuf& img, int channel)
{
    double sum = 0;
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x) {
            double d = img.getchannel(x, y, 0, channel) - (x < 32 ? 0.2 : 0.8);
            sum += d * d;
        }
    return sum / (64 * 64);
}

PrefilterOptions generic()
{
    PrefilterOptions o;
    o.aovs.preset = "generic";
    // The colour of noisy_features is converged (relative standard error ~0.07, mcdn/skip.h):
    // with skipping on, its tiles' features would pass through unfiltered.
    o.skip.enabled = false;
    return o;
}

}  // namespace

TEST(Prefilter, ReducesFeatureNoiseAndKeepsTheEdge)
{
    OIIO::ImageBuf in = noisy_features(0.05f);
    OIIO::ImageBuf out = prefilter(in, generic());
    ASSERT_FALSE(out.has_error()) << out.geterror();
    int mean = in.spec().channelindex("albedo.R"), half_a = in.spec().channelindex("A.albedo.R");
    EXPECT_LT(feature_mse(out, mean), 0.1 * feature_mse(in, mean));
    EXPECT_LT(feature_mse(out, half_a), 0.2 * feature_mse(in, half_a));
    // The edge survives: pixels two columns away from it keep their side's value.
    EXPECT_NEAR(out.getchannel(29, 30, 0, mean), 0.2f, 0.03f);
    EXPECT_NEAR(out.getchannel(34, 30, 0, mean), 0.8f, 0.03f);
    EXPECT_EQ(out.spec().get_int_attribute("mcdn:prefiltered"), 1);
    EXPECT_EQ(out.nchannels(), in.nchannels());
    // The colour is not a feature: untouched.
    EXPECT_EQ(out.getchannel(3, 4, 0, 0), in.getchannel(3, 4, 0, 0));
}

TEST(Prefilter, ConstantFeatureStaysConstant)
{
    OIIO::ImageBuf in = mcdn_test::make_image(
        40, 24, generic_channels(), [](int, int, int ch) { return ch / 6 == 1 ? 0.0f : 0.375f; });
    OIIO::ImageBuf out = prefilter(in, generic());
    ASSERT_FALSE(out.has_error()) << out.geterror();
    int mean = in.spec().channelindex("albedo.G");
    for (int y = 0; y < 24; ++y)
        for (int x = 0; x < 40; ++x)
            ASSERT_FLOAT_EQ(out.getchannel(x, y, 0, mean), 0.375f);
}

TEST(Prefilter, NanFeatureVarianceAndThreadIndependence)
{
    OIIO::ImageBuf in;
    ASSERT_TRUE(read_inputs(in, { { mcdn_test::test_data("cornell20"), InputKind::Mean } }))
        << in.geterror();
    PrefilterOptions o;
    o.aovs.preset = "tungsten";
    OIIO::ImageBuf one = prefilter(in, o, {}, 1);
    OIIO::ImageBuf two = prefilter(in, o, {}, 2);
    ASSERT_FALSE(one.has_error()) << one.geterror();
    EXPECT_TRUE(all_finite(one));
    std::vector<float> a(one.spec().image_pixels() * one.nchannels()), b(a.size());
    one.get_pixels(one.roi(), OIIO::TypeDesc::FLOAT, a.data());
    two.get_pixels(two.roi(), OIIO::TypeDesc::FLOAT, b.data());
    EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(float)));
}

TEST(Prefilter, NoFeaturesIsAnError)
{
    OIIO::ImageBuf in =
        mcdn_test::make_image(8, 8, { "R", "G", "B" }, [](int, int, int) { return 1.0f; });
    OIIO::ImageBuf out;
    EXPECT_FALSE(prefilter(out, in, generic()));
    EXPECT_NE(out.geterror().find("prefilter"), std::string::npos);
}

TEST(Prefilter, UnknownExtraFeatureIsAnError)
{
    OIIO::ImageBuf in = noisy_features(0.01f);
    PrefilterOptions o = generic();
    o.extra_features = { "roughness" };
    OIIO::ImageBuf out;
    EXPECT_FALSE(prefilter(out, in, o));
    std::string error = out.geterror();
    EXPECT_NE(error.find("roughness"), std::string::npos) << error;
}

TEST(Prefilter, ExtraFeatureIsFiltered)
{
    // The albedo channels double as an "extra" feature under another name.
    OIIO::ImageBuf in = noisy_features(0.05f);
    PrefilterOptions o = generic();
    o.aovs.overrides["albedo"] = { "R", "G", "B" };  // colour as albedo: irrelevant here
    o.extra_features = { "albedo.R" };
    OIIO::ImageBuf out = prefilter(in, o);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    int mean = in.spec().channelindex("albedo.R");
    EXPECT_LT(feature_mse(out, mean), 0.1 * feature_mse(in, mean));
}
