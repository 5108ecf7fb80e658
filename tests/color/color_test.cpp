// Colour management: working space, matrices read off OCIO, which channels convert.
#include "mcdn/color.h"

#include <cstdlib>

#include "mcdn/io.h"

#include "mcdn_test.h"

using namespace mcdn;

namespace {

ImageBuf box16()
{
    ImageBuf merged;
    std::string dir = mcdn_test::test_data("box16/");
    EXPECT_TRUE(read_inputs(merged, { { dir + "box_0016spp.exr", InputKind::Mean },
                                      { dir + "box_0016spp_var.exr", InputKind::Variance } }));
    return merged;
}

AovSet resolve(const ImageBuf& buf)
{
    AovSet set;
    std::string error;
    EXPECT_TRUE(resolve_aovs(set, AovSpec(), buf.spec(), error)) << error;
    return set;
}

std::vector<float> pixel(const ImageBuf& buf, int x, int y)
{
    std::vector<float> px(buf.nchannels());
    buf.getpixel(x, y, px.data(), buf.nchannels());
    return px;
}

}  // namespace

TEST(Color, WorkingSpaceIsTheScenelinearRoleOfOurConfig)
{
    EXPECT_EQ(working_colorspace(), "lin_rec709");
    EXPECT_NE(ocio_config_path().find("config.ocio"), std::string::npos);
}

TEST(Color, InputSpaceComesFromTheSpecThenTheFileThenTheRole)
{
    ImageBuf box = box16();
    EXPECT_EQ(box.spec().get_string_attribute("oiio:ColorSpace"), "Linear");
    AovSpec spec;
    EXPECT_EQ(input_colorspace(spec, box.spec()), "lin_rec709");  // "Linear" is an alias
    spec.colorspace = "acescg";
    EXPECT_EQ(input_colorspace(spec, box.spec()), "acescg");
    ImageSpec untagged(4, 4, 3);
    EXPECT_EQ(input_colorspace(AovSpec(), untagged), "lin_rec709");
}

// A tag or a name the config does not know is an error naming it and the config, never the
// working space unsaid; OIIO's generic "Linear" leaves the choice to the chromaticities.
TEST(Color, UnknownNamesAreErrorsAndChromaticitiesAreRead)
{
    std::string name, why, error;
    ImageSpec tagged(4, 4, 3);
    tagged.attribute("oiio:ColorSpace", "Weird Gamut");
    EXPECT_FALSE(input_colorspace(name, why, AovSpec(), tagged, error));
    EXPECT_NE(error.find("'Weird Gamut'"), std::string::npos) << error;
    EXPECT_NE(error.find("config.ocio"), std::string::npos) << error;
    AovSpec named;
    named.colorspace = "nonesuch";
    EXPECT_FALSE(input_colorspace(name, why, named, ImageSpec(4, 4, 3), error));
    EXPECT_NE(error.find("'nonesuch'"), std::string::npos) << error;

    ImageSpec ap0(4, 4, 3);
    ap0.attribute("oiio:ColorSpace", "Linear");
    const float xy[8] = { 0.7347f, 0.2653f, 0.0f, 1.0f, 0.0001f, -0.077f, 0.32168f, 0.33767f };
    ap0.attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), xy);
    ASSERT_TRUE(input_colorspace(name, why, AovSpec(), ap0, error)) << error;
    EXPECT_EQ(name, "aces2065_1");
    EXPECT_NE(why.find("AP0"), std::string::npos) << why;
}

TEST(Color, MatricesAndNonLinearSpaces)
{
    std::array<double, 9> m;
    std::string error;
    ASSERT_TRUE(linear_transform(m, "lin_rec709", "acescg", error)) << error;
    EXPECT_NEAR(m[0], 0.6131, 1e-4);
    EXPECT_NEAR(m[1], 0.3395, 1e-4);
    EXPECT_NEAR(m[3], 0.0702, 1e-4);
    EXPECT_FALSE(linear_transform(m, "lin_rec709", "srgb_display", error));
    EXPECT_NE(error.find("not scene-linear"), std::string::npos) << error;
    EXPECT_FALSE(linear_transform(m, "lin_rec709", "no_such_space", error));
    EXPECT_NE(error.find("unknown colour space 'no_such_space'"), std::string::npos) << error;
}

// An 8-bit PNG's sRGB: no matrix, OCIO's curve per pixel, there and back; a variance in
// such a space cannot be converted.
TEST(Color, DisplayEncodedColourIsConvertedPerPixelAndItsVarianceRefused)
{
    ImageBuf ldr = mcdn_test::make_image(2, 1, { "R", "G", "B" },
                                         [](int x, int, int c) { return x ? 1.0f : 0.5f; });
    AovSpec spec;
    spec.preset = "generic";
    AovSet set;
    std::string error;
    ASSERT_TRUE(resolve_aovs(set, spec, ldr.spec(), error)) << error;
    ASSERT_TRUE(convert_color_channels(ldr, set, "srgb_display", "lin_rec709", error)) << error;
    EXPECT_NEAR(ldr.getchannel(0, 0, 0, 1), 0.2140, 1e-3);  // the sRGB curve, not a matrix
    EXPECT_NEAR(ldr.getchannel(1, 0, 0, 1), 1.0, 1e-4);
    ASSERT_TRUE(convert_color_channels(ldr, set, "lin_rec709", "srgb_display", error)) << error;
    EXPECT_NEAR(ldr.getchannel(0, 0, 0, 1), 0.5, 1e-4);

    ImageBuf with_variance =
        mcdn_test::make_image(2, 1, { "R", "G", "B", "variance.R", "variance.G", "variance.B" },
                              [](int, int, int) { return 0.5f; });
    ASSERT_TRUE(resolve_aovs(set, spec, with_variance.spec(), error)) << error;
    EXPECT_FALSE(convert_color_channels(with_variance, set, "srgb_display", "lin_rec709", error));
    EXPECT_NE(error.find("'srgb_display' is not linear"), std::string::npos) << error;
}

// EXR chromaticities of other primaries: their own matrix. P3-D65's red in Rec.709 is the
// first column of the published P3 -> Rec.709 matrix; XYZ (white E) keeps white white.
TEST(Color, OtherPrimariesAreConvertedByTheirMatrix)
{
    ImageSpec p3(2, 1, 3);
    const float xy[8] = { 0.680f, 0.320f, 0.265f, 0.690f, 0.150f, 0.060f, 0.3127f, 0.3290f };
    p3.attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), xy);
    std::string name, why, error;
    ASSERT_TRUE(input_colorspace(name, why, AovSpec(), p3, error)) << error;
    EXPECT_EQ(name.rfind("primaries ", 0), 0u) << name;
    ImageBuf red = mcdn_test::make_image(
        2, 1, { "R", "G", "B" }, [](int x, int, int c) { return x ? 1.0f : float(c == 0); });
    AovSpec generic;
    generic.preset = "generic";
    AovSet set;
    ASSERT_TRUE(resolve_aovs(set, generic, red.spec(), error)) << error;
    ASSERT_TRUE(convert_color_channels(red, set, name, "lin_rec709", error)) << error;
    EXPECT_NEAR(red.getchannel(0, 0, 0, 0), 1.2249, 2e-3);
    EXPECT_NEAR(red.getchannel(0, 0, 0, 1), -0.0421, 2e-3);
    EXPECT_NEAR(red.getchannel(0, 0, 0, 2), -0.0196, 2e-3);
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(red.getchannel(1, 0, 0, c), 1.0, 1e-4) << "white stays white";
    ASSERT_TRUE(convert_color_channels(red, set, "lin_rec709", name, error)) << error;
    EXPECT_NEAR(red.getchannel(0, 0, 0, 0), 1.0, 1e-4);
    EXPECT_NEAR(red.getchannel(0, 0, 0, 1), 0.0, 1e-4);

    const float xyz[8] = { 1, 0, 0, 1, 0, 0, 1.0f / 3, 1.0f / 3 };
    ImageSpec e(2, 1, 3);
    e.attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), xyz);
    ASSERT_TRUE(input_colorspace(name, why, AovSpec(), e, error)) << error;
    ImageBuf white =
        mcdn_test::make_image(1, 1, { "R", "G", "B" }, [](int, int, int) { return 1.0f; });
    ASSERT_TRUE(convert_color_channels(white, set, name, "lin_rec709", error)) << error;
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(white.getchannel(0, 0, 0, c), 1.0, 1e-4) << "E white is D65 white";
}

TEST(Color, ConvertsColorAndVarianceButNeverData)
{
    ImageBuf box = box16();
    AovSet set = resolve(box);
    ImageBuf converted = box.copy(OIIO::TypeDesc::FLOAT);
    std::string error;
    ASSERT_TRUE(convert_color_channels(converted, set, "lin_rec709", "acescg", error)) << error;
    std::array<double, 9> m;
    ASSERT_TRUE(linear_transform(m, "lin_rec709", "acescg", error));
    auto before = pixel(box, 20, 30), after = pixel(converted, 20, 30);
    const auto& c = set.channels(Role::Color);
    const auto& v = set.channels(Role::ColorVariance);
    const auto& a = set.channels(Role::Albedo);
    double expected_g = m[3] * before[c[0]] + m[4] * before[c[1]] + m[5] * before[c[2]];
    EXPECT_NEAR(after[c[1]], expected_g, 1e-6 + 1e-5 * std::fabs(expected_g));
    double expected_var =
        m[3] * m[3] * before[v[0]] + m[4] * m[4] * before[v[1]] + m[5] * m[5] * before[v[2]];
    EXPECT_NEAR(after[v[1]], expected_var, 1e-9 + 1e-5 * expected_var);
    double expected_albedo = m[0] * before[a[0]] + m[1] * before[a[1]] + m[2] * before[a[2]];
    EXPECT_NEAR(after[a[0]], expected_albedo, 1e-6);
    for (Role data : { Role::Normal, Role::Depth, Role::NormalVariance })
        for (int ch : set.channels(data))
            EXPECT_EQ(after[ch], before[ch]) << role_name(data);

    ASSERT_TRUE(convert_color_channels(converted, set, "acescg", "lin_rec709", error)) << error;
    auto back = pixel(converted, 20, 30);
    for (int ch : c)
        EXPECT_NEAR(back[ch], before[ch], 1e-5 * (1 + std::fabs(before[ch])));
}

TEST(Color, OpsSeeTheWorkingSpaceAndResultsGoBack)
{
    ImageBuf box = box16();
    AovSpec acescg;
    acescg.colorspace = "acescg";
    ImageBuf in_aces = box.copy(OIIO::TypeDesc::FLOAT);
    std::string error;
    ASSERT_TRUE(convert_color_channels(in_aces, resolve(box), "lin_rec709", "acescg", error));
    // An op that records what it saw and doubles the colour.
    std::vector<float> seen;
    auto op = [&](ImageBuf& dst, const ImageBuf& src) {
        seen = pixel(src, 5, 5);
        dst.copy(src, OIIO::TypeDesc::FLOAT);
        AovSet set = resolve(src);
        for (int y = 0; y < 64; ++y)
            for (int x = 0; x < 64; ++x) {
                auto px = pixel(src, x, y);
                for (int ch : set.channels(Role::Color))
                    px[ch] *= 2;
                dst.setpixel(x, y, px.data(), int(px.size()));
            }
        return true;
    };
    ImageBuf out;
    ASSERT_TRUE(run_in_working_space(out, in_aces, acescg, "test", op)) << out.geterror();
    auto original = pixel(box, 5, 5), result = pixel(out, 5, 5), aces = pixel(in_aces, 5, 5);
    AovSet set = resolve(box);
    for (int ch : set.channels(Role::Color)) {
        EXPECT_NEAR(seen[ch], original[ch], 1e-5 * (1 + original[ch]));  // op saw Rec.709
        EXPECT_NEAR(result[ch], 2 * aces[ch], 1e-5 * (1 + aces[ch]));    // result is ACEScg
    }
    EXPECT_EQ(out.spec().get_int_attribute("mcdn:in_working_space"), 0);
}

// Blender's light passes hold light divided by their colour pass (DiffDir = diffuse direct
// light / DiffCol): the ops see the light, factor × pass, and the way back divides it out,
// by Cycles' rule where a factor channel is 0 (the other channels' mean quotient).
TEST(Color, LightPassesAreLightInTheWorkingSpace)
{
    const std::vector<std::string> names = {
        "L.Combined.R", "L.Combined.G",         "L.Combined.B",         "L.DiffCol.R",
        "L.DiffCol.G",  "L.DiffCol.B",          "L.DiffDir.R",          "L.DiffDir.G",
        "L.DiffDir.B",  "variance.L.DiffDir.R", "variance.L.DiffDir.G", "variance.L.DiffDir.B",
    };
    // Pixel 0: an ordinary albedo; pixel 1: a red material (DiffCol's G and B are 0).
    const float values[2][12] = { { 1, 1, 1, 0.5f, 0.25f, 0.8f, 2, 3, 4, 0.1f, 0.2f, 0.3f },
                                  { 1, 0, 0, 0.6f, 0, 0, 1.5f, 1.5f, 1.5f, 0.1f, 0.1f, 0.1f } };
    ImageBuf buf =
        mcdn_test::make_image(2, 1, names, [&](int x, int, int c) { return values[x][c]; });
    AovSpec spec;
    spec.preset = "cycles";
    AovSet set;
    std::string error;
    ASSERT_TRUE(resolve_aovs(set, spec, buf.spec(), error)) << error;
    ASSERT_TRUE(set.has_factored_extras());
    ASSERT_TRUE(needs_working_conversion(buf.spec(), "lin_rec709", set));
    ASSERT_TRUE(into_working_space(buf, set, "lin_rec709", error)) << error;
    EXPECT_FALSE(needs_working_conversion(buf.spec(), "lin_rec709", set)) << "converted once";
    EXPECT_FLOAT_EQ(buf.getchannel(0, 0, 0, 6), 1.0f);                   // 0.5 · 2
    EXPECT_FLOAT_EQ(buf.getchannel(0, 0, 0, 8), 3.2f);                   // 0.8 · 4
    EXPECT_FLOAT_EQ(buf.getchannel(0, 0, 0, 10), 0.2f * 0.25f * 0.25f);  // variance · factor²
    EXPECT_FLOAT_EQ(buf.getchannel(1, 0, 0, 7), 0.0f);  // no green light on a red material
    // A denoiser moved the light: the way back divides the factor out again.
    buf.setpixel(1, 0, std::vector<float> { 1, 0, 0, 0.6f, 0, 0, 1.2f, 0.1f, 0.0f, 0, 0, 0 }.data(),
                 12);
    ASSERT_TRUE(out_of_working_space(buf, set, "lin_rec709", error)) << error;
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(buf.getchannel(0, 0, 0, 6 + c), values[0][6 + c], 1e-6) << c;
    EXPECT_NEAR(buf.getchannel(0, 0, 0, 10), 0.2f, 1e-6);
    EXPECT_FLOAT_EQ(buf.getchannel(1, 0, 0, 6), 2.0f);  // 1.2 / 0.6
    EXPECT_FLOAT_EQ(buf.getchannel(1, 0, 0, 7), 2.0f);  // Cycles: the red quotient
    EXPECT_FLOAT_EQ(buf.getchannel(1, 0, 0, 8), 2.0f);
    EXPECT_EQ(buf.spec().get_int_attribute("mcdn:in_working_space"), 0);

    // Without its colour pass a DiffDir is not light: not an extra, left as rendered.
    ImageBuf alone = mcdn_test::make_image(1, 1,
                                           { "L.Combined.R", "L.Combined.G", "L.Combined.B",
                                             "L.DiffDir.R", "L.DiffDir.G", "L.DiffDir.B" },
                                           [](int, int, int) { return 1.0f; });
    ASSERT_TRUE(resolve_aovs(set, spec, alone.spec(), error)) << error;
    EXPECT_TRUE(set.extras().empty());
}
