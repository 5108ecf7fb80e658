// mcdn::nfor: properties (exact fit of a feature-explained ramp, constants, robustness,
// thread independence) and golden tests on the fixtures against the reference NFOR output.
#include <cstring>

#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "fixtures.h"
#include "nfor_support.h"

using namespace mcdn;
using namespace nfor_test;

namespace {

NforOptions generic_options()
{
    NforOptions o;
    o.aovs.preset = "generic";
    return o;
}

std::vector<float> pixels(const OIIO::ImageBuf& img)
{
    std::vector<float> px(img.spec().image_pixels() * img.nchannels());
    img.get_pixels(img.roi(), OIIO::TypeDesc::FLOAT, px.data());
    return px;
}

OIIO::ImageBuf read_fixture(const std::string& name, std::string& preset)
{
    preset = name == "cornell20" ? "tungsten" : "cycles";
    return name == "cornell20" ? mcdn_test::cornell20() : mcdn_test::box16();
}

std::vector<int> color_channels(const OIIO::ImageBuf& merged, const std::string& preset)
{
    AovSpec spec;
    spec.preset = preset;
    AovSet aovs;
    std::string error;
    EXPECT_TRUE(resolve_aovs(aovs, spec, merged.spec(), error)) << error;
    return aovs.channels(Role::Color);
}

}  // namespace

// A colour that is an affine function of a textured feature is reconstructed far below the
// noise: the first-order model explains it exactly (albedo R = G = B also tests collinear
// features falling back to a lower-order fit).
TEST(Nfor, FeatureExplainedRampIsReconstructed)
{
    Scene s;
    s.albedo = [](int x, int y, int) {
        return 0.5f + 0.4f * std::sin(0.37f * x) * std::cos(0.23f * y);
    };
    s.color = [&](int x, int y, int c) {
        return 0.1f + 0.1f * c + 0.8f * s.albedo(x, y, c) + 0.002f * x;
    };
    OIIO::ImageBuf in = render(s);
    double noisy = mse_against(in, s);
    OIIO::ImageBuf out = nfor(in, generic_options(), {}, 0);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    double denoised = mse_against(out, s);
    EXPECT_LT(denoised, 0.03 * noisy) << "noisy MSE " << noisy;
}

TEST(Nfor, ConstantImageStaysConstant)
{
    Scene s;
    s.sigma_half = 0.0f;
    s.albedo = [](int, int, int) { return 0.3f; };
    s.color = [](int, int, int c) { return 0.25f + 0.25f * c; };
    OIIO::ImageBuf out = nfor(render(s), generic_options(), {}, 0);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    for (int y = 0; y < 64; ++y)
        for (int x = 0; x < 64; ++x)
            for (int c = 0; c < 3; ++c)
                ASSERT_NEAR(out.getchannel(x, y, 0, c), 0.25f + 0.25f * c, 1e-5f) << x << "," << y;
}

TEST(Nfor, NanInfAndHugeInputsGiveFiniteOutput)
{
    Scene s;
    s.albedo = [](int x, int, int) { return 0.1f * (x % 7); };
    s.color = [](int x, int y, int) { return 0.5f + 0.01f * ((x * y) % 13); };
    OIIO::ImageBuf in = render(s);
    const float bad[] = { std::nanf(""), INFINITY, -INFINITY, 1e30f, -1e30f, 1e20f };
    int n = 0;
    for (int y = 3; y < 64; y += 7)
        for (int x = 5; x < 64; x += 5)
            for (int c = 0; c < in.nchannels(); c += 5)
                in.setpixel(x, y, 0, &bad[n++ % 6], 1), (void)c;
    // Bad values in every kind of channel: colour, variance, halves, features.
    for (int c = 0; c < in.nchannels(); ++c) {
        float v = bad[c % 6];
        float px[24];
        in.getpixel(10 + c, 20, px, 24);
        px[c] = v;
        in.setpixel(10 + c, 20, px, 24);
    }
    // A whole row of zero variance and a column of NaN feature variance.
    for (int x = 0; x < 64; ++x) {
        float px[24];
        in.getpixel(x, 40, px, 24);
        px[6] = px[7] = px[8] = 0.0f;
        px[9] = px[10] = px[11] = std::nanf("");
        in.setpixel(x, 40, px, 24);
    }
    NforOptions o = generic_options();
    o.output_mse = o.output_selection = true;
    OIIO::ImageBuf out = nfor(in, o, {}, 0);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    // What the op writes is finite (the other channels pass through as they came).
    for (const char* name : { "R", "G", "B", "nfor.mse.R", "nfor.mse.G", "nfor.mse.B",
                              "nfor.selection.R", "nfor.selection.G", "nfor.selection.B" }) {
        int c = out.spec().channelindex(name);
        ASSERT_GE(c, 0) << name;
        for (int y = 0; y < 64; ++y)
            for (int x = 0; x < 64; ++x)
                ASSERT_TRUE(std::isfinite(out.getchannel(x, y, 0, c)))
                    << name << " " << x << "," << y;
    }
    // Away from the bad pixels the result is still a denoised image, not zeros.
    EXPECT_NEAR(out.getchannel(2, 62, 0, 0), 0.5f + 0.01f * ((2 * 62) % 13), 0.1f);
}

TEST(Nfor, OutputIdenticalForOneAndTwoThreads)
{
    std::string preset;
    OIIO::ImageBuf in = read_fixture("cornell20", preset);
    NforOptions o;
    o.aovs.preset = preset;
    o.output_mse = o.output_selection = true;
    OIIO::ImageBuf one = nfor(in, o, {}, 1);
    OIIO::ImageBuf two = nfor(in, o, {}, 2);
    ASSERT_FALSE(one.has_error()) << one.geterror();
    std::vector<float> a = pixels(one), b = pixels(two);
    ASSERT_EQ(a.size(), b.size());
    EXPECT_EQ(0, std::memcmp(a.data(), b.data(), a.size() * sizeof(float)));
}

TEST(Nfor, KeepsChannelsAndAddsMaps)
{
    std::string preset;
    OIIO::ImageBuf in = read_fixture("box16", preset);
    NforOptions o;
    o.aovs.preset = preset;
    o.output_mse = o.output_selection = true;
    OIIO::ImageBuf out = nfor(in, o, {}, 0);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    EXPECT_EQ(out.nchannels(), in.nchannels() + 6);
    for (const char* name : { "nfor.mse.R", "nfor.selection.B" })
        EXPECT_GE(out.spec().channelindex(name), 0) << name;
    int sel = out.spec().channelindex("nfor.selection.G");
    for (int y = 0; y < 64; y += 9)
        for (int x = 0; x < 64; x += 9) {
            float v = out.getchannel(x, y, 0, sel);
            EXPECT_TRUE(v >= 0.0f && v <= 1.0f) << v;
        }
    EXPECT_TRUE(all_finite(out));
    // Channels other than the colour are untouched.
    int albedo = in.spec().channelindex("ViewLayer.Denoising Albedo.R");
    ASSERT_GE(albedo, 0);
    EXPECT_EQ(in.getchannel(7, 9, 0, albedo), out.getchannel(7, 9, 0, albedo));
}

TEST(Nfor, MissingHalvesIsAnErrorNamingTheRole)
{
    OIIO::ImageBuf in =
        mcdn_test::make_image(16, 16, { "R", "G", "B" }, [](int, int, int) { return 0.5f; });
    OIIO::ImageBuf out;
    EXPECT_FALSE(nfor(out, in, generic_options()));
    std::string error = out.geterror();
    EXPECT_NE(error.find("nfor needs two half buffers or the colour's variance"), std::string::npos)
        << error;
    EXPECT_NE(error.find("color_a, color_b, color_variance"), std::string::npos) << error;
}

// A renderer's colour and variance without halves (Arnold, RenderMan): the one-buffer path,
// SURE picking the bandwidth; below the render's error, the same for any thread count, and
// what nfor:halves=0 gives on an input that has halves.
TEST(Nfor, OneBufferPathWithoutHalves)
{
    const std::string b = mcdn_test::test_data("box16/box_0016spp");
    OIIO::ImageBuf in;
    ASSERT_TRUE(read_inputs(
        in, { { b + ".exr", InputKind::Mean }, { b + "_var.exr", InputKind::Variance } }));
    NforOptions o;
    OIIO::ImageBuf one = nfor(in, o, {}, 1), two = nfor(in, o, {}, 2);
    ASSERT_FALSE(one.has_error()) << one.geterror();
    EXPECT_EQ(pixels(one), pixels(two));
    std::vector<int> rgb = color_channels(in, "cycles");
    const std::string ref = mcdn_test::test_data("box16/box_ref.exr");
    const double noisy = relmse(in, rgb, ref), denoised = relmse(one, rgb, ref);
    EXPECT_LT(denoised, 0.25 * noisy) << "render " << noisy;
    OIIO::ImageBuf full = mcdn_test::box16();
    o.use_halves = false;
    OIIO::ImageBuf without = nfor(full, o);
    ASSERT_FALSE(without.has_error()) << without.geterror();
    EXPECT_DOUBLE_EQ(relmse(without, color_channels(full, "cycles"), ref), denoised);
}

TEST(Nfor, RoiLimitsTheWrittenPixels)
{
    std::string preset;
    OIIO::ImageBuf in = read_fixture("box16", preset);
    NforOptions o;
    o.aovs.preset = preset;
    OIIO::ImageBuf full = nfor(in, o);
    OIIO::ImageBuf part = nfor(in, o, OIIO::ROI(0, 32, 0, 64));
    int r = color_channels(in, preset)[0];
    EXPECT_EQ(part.getchannel(10, 10, 0, r), full.getchannel(10, 10, 0, r));
    EXPECT_EQ(part.getchannel(40, 10, 0, r), in.getchannel(40, 10, 0, r));
}

// Golden tests on the 64×64 fixtures. The fixture's reference-implementation output is a crop
// of its full-frame result, which saw context beyond the crop's borders that a run on the crop
// cannot; on the crop we allow 1.4× its relMSE (we measure 1.30×). The README's 1.05× criterion
// is checked on the full frames (NforShared, bench_nfor).
TEST(NforGolden, Cornell20FixtureMatchesReferenceImplementation)
{
    std::string preset;
    OIIO::ImageBuf in = read_fixture("cornell20", preset);
    NforOptions o;
    o.aovs.preset = preset;
    OIIO::ImageBuf out = nfor(in, o);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    std::vector<int> rgb = color_channels(in, preset);
    double ours = relmse(out, rgb, mcdn_test::test_data("cornell20/ref.pfm"));
    OIIO::ImageBuf refimpl;
    ASSERT_TRUE(read_image(refimpl, mcdn_test::test_data("cornell20/nfor_reference.pfm")));
    double theirs = relmse(refimpl, { 0, 1, 2 }, mcdn_test::test_data("cornell20/ref.pfm"));
    double noisy = relmse(in, rgb, mcdn_test::test_data("cornell20/ref.pfm"));
    EXPECT_LT(ours, 0.5 * noisy);
    EXPECT_LT(ours, 1.4 * theirs) << "reference implementation " << theirs;
}

TEST(NforGolden, BoxFixtureChainedWithPrefilter)
{
    std::string preset;
    OIIO::ImageBuf in = read_fixture("box16", preset);
    PrefilterOptions po;
    po.aovs.preset = preset;
    NforOptions o;
    o.aovs.preset = preset;
    OIIO::ImageBuf pre = prefilter(in, po);
    ASSERT_FALSE(pre.has_error()) << pre.geterror();
    OIIO::ImageBuf chained = nfor(pre, o);
    OIIO::ImageBuf direct = nfor(in, o);  // prefilters internally
    ASSERT_FALSE(chained.has_error()) << chained.geterror();
    std::vector<int> rgb = color_channels(in, preset);
    double a = relmse(chained, rgb, mcdn_test::test_data("box16/box_ref.exr"));
    double b = relmse(direct, rgb, mcdn_test::test_data("box16/box_ref.exr"));
    double noisy = relmse(in, rgb, mcdn_test::test_data("box16/box_ref.exr"));
    EXPECT_DOUBLE_EQ(a, b);
    EXPECT_LT(a, 0.2 * noisy);
}

// The full inputs of ../shared/data against the README's table (skipped in a user's clone).
TEST(NforShared, Cornell20WithinFivePercentOfReferenceImplementation)
{
    MCDN_REQUIRE_SHARED(dir, "tungsten/cornell20");
    OIIO::ImageBuf in;
    ASSERT_TRUE(read_inputs(in, { { dir, InputKind::Mean } })) << in.geterror();
    NforOptions o;
    o.aovs.preset = "tungsten";
    OIIO::ImageBuf out = nfor(in, o);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    double ours = relmse(out, color_channels(in, "tungsten"), dir + "/ref.pfm");
    EXPECT_LT(ours, 1.05 * 0.00075);
}
