// SURE: unbiased estimate of a denoiser's MSE (PD eq. 1-2), on renders with a known truth.
#include "mcdn/sure.h"

#include <OpenImageIO/imagebufalgo.h>

#include "synthetic.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

float gradient(int x, int y, int c)
{
    return 0.2f + 0.004f * x + 0.002f * y + 0.1f * c;
}
float checker(int x, int y, int c)
{
    return ((x / 4 + y / 4) % 2) ? 0.8f : 0.1f + 0.05f * c;
}

double true_mse(const ImageBuf& result, const ImageBuf& truth)
{
    ImageBuf rgb = OIIO::ImageBufAlgo::channels(result, 3, { 0, 1, 2 });
    auto comp = OIIO::ImageBufAlgo::compare(rgb, truth, 0, 0);
    return comp.rms_error * comp.rms_error;
}

int channel(const ImageBuf& buf, const char* name)
{
    return buf.spec().channelindex(name);
}

}  // namespace

TEST(Sure, DivergenceOfABoxBlurIsVarianceOverKernelSize)
{
    const float variance = 0.01f;
    ImageBuf src = noisy_render(96, 96, gradient, variance, 1);
    SureOptions options;
    options.aovs = generic_spec();
    options.probes = 4;
    ImageBuf out;
    ASSERT_TRUE(sure(out, src, box_denoiser(1), options)) << out.geterror();
    // Interior pixels: sigma^2 f'(x) = variance / 9 in expectation.
    ROI interior(4, 92, 4, 92);
    auto stats = OIIO::ImageBufAlgo::computePixelStats(out, interior);
    int d = channel(out, "sure.divergence.G");
    EXPECT_NEAR(stats.avg[d], variance / 9, 0.05 * variance / 9);
}

namespace {

/// The spread over pixels of f'(x) = divergence / variance outside `skip` (the pixels a
/// heavy pixel's own probe reaches through the blur), and its mean.
std::pair<double, double> divergence_mean_and_spread(const ImageBuf& out, float variance,
                                                     ROI interior, ROI skip)
{
    const int d = out.spec().channelindex("sure.divergence.G");
    double sum = 0, sum2 = 0;
    int n = 0;
    for (int y = interior.ybegin; y < interior.yend; ++y)
        for (int x = interior.xbegin; x < interior.xend; ++x) {
            if (skip.contains(x, y))
                continue;
            const double f = out.getchannel(x, y, 0, d) / variance;
            sum += f;
            sum2 += f * f;
            ++n;
        }
    const double mean = sum / n;
    return { mean, std::sqrt(sum2 / n - mean * mean) };
}

}  // namespace

TEST(Sure, OneHugeVariancePixelLeavesTheOthersProbed)
{
    // A caustic seen through glass: one pixel's variance is 1e12 times the others'. The
    // probe step is set by the frame's standard deviations; were it set by their RMS (here
    // the one pixel's), every other pixel would move by about a float ulp and its
    // difference quotient would measure the blur's round-off: a spread of f' several
    // times the clean frame's. The box blur's f' is 1/9 either way.
    const float variance = 0.01f;
    SureOptions options;
    options.aovs = generic_spec();
    options.probes = 4;
    ImageBuf clean = noisy_render(128, 128, gradient, variance, 11);
    ImageBuf heavy = clean;
    float px[12];
    heavy.getpixel(64, 64, px, 12);
    for (int c = 3; c < 6; ++c)
        px[c] = variance * 1e12f;
    heavy.setpixel(64, 64, px, 12);
    const ROI interior(4, 124, 4, 124), near_heavy(63, 66, 63, 66);
    auto [clean_mean, clean_spread] = divergence_mean_and_spread(
        sure(clean, box_denoiser(1), options), variance, interior, near_heavy);
    ImageBuf out = sure(heavy, box_denoiser(1), options);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    auto [mean, spread] = divergence_mean_and_spread(out, variance, interior, near_heavy);
    EXPECT_NEAR(clean_mean, 1.0 / 9, 0.05 / 9);
    EXPECT_NEAR(mean, 1.0 / 9, 0.05 / 9);
    EXPECT_NEAR(spread, clean_spread, 0.1 * clean_spread);
}

TEST(Sure, MeanSureMatchesTheTrueMse)
{
    // 4 renders of 256x256x3: the mean of per-pixel SURE has a relative standard deviation
    // of about 4% here (each pixel's estimate has std ~ 1.4 sigma^2 against an MSE of
    // sigma^2 / 25), so 12% is a 3-sigma bound.
    for (auto truth : { gradient, checker }) {
        const float variance = 0.02f;
        double estimate = 0, actual = 0;
        for (unsigned seed : { 7u, 8u, 9u, 10u }) {
            ImageBuf src = noisy_render(256, 256, truth, variance, seed);
            SureOptions options;
            options.aovs = generic_spec();
            ImageBuf out;
            ASSERT_TRUE(sure(out, src, box_denoiser(2), options)) << out.geterror();
            for (const char* name : sure_channels::kSure)
                estimate += channel_mean(out, channel(out, name)) / 12;
            actual += true_mse(out, truth_image(256, 256, truth)) / 4;
        }
        EXPECT_NEAR(estimate, actual, 0.12 * actual);
    }
}

TEST(Sure, OutputsTheDenoisedColorTheRenderAndTheTerms)
{
    ImageBuf src = noisy_render(32, 32, gradient, 0.01f, 3);
    SureOptions options;
    options.aovs = generic_spec();
    ImageBuf out = sure(src, box_denoiser(1), options);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    ImageBuf expected;
    box_denoiser(1)(expected, src);
    float a[32], b[32];
    out.getpixel(10, 11, a, 32);
    expected.getpixel(10, 11, b, 12);
    EXPECT_EQ(a[0], b[0]);  // colour = y
    float x[12];
    src.getpixel(10, 11, x, 12);
    EXPECT_EQ(a[channel(out, "noisy.R")], x[0]);  // noisy.* = x
    double residual = (b[1] - x[1]) * double(b[1] - x[1]);
    EXPECT_NEAR(a[channel(out, "sure.residual.G")], residual, 1e-6);
    EXPECT_NEAR(a[channel(out, "sure.G")],
                residual + 2 * a[channel(out, "sure.divergence.G")] - 0.01, 1e-5);
}

TEST(Sure, DeterministicAndFiniteOnBadPixels)
{
    ImageBuf src = noisy_render(32, 32, gradient, 0.01f, 5);
    float px[12];
    src.getpixel(4, 4, px, 12);
    px[3] = 0.0f;  // zero variance pixel
    src.setpixel(4, 4, px, 12);
    SureOptions options;
    options.aovs = generic_spec();
    ImageBuf one = sure(src, box_denoiser(1), options, {}, 1);
    ImageBuf two = sure(src, box_denoiser(1), options, {}, 2);
    auto comp = OIIO::ImageBufAlgo::compare(one, two, 0, 0);
    EXPECT_EQ(comp.maxerror, 0.0);
    EXPECT_FALSE(OIIO::ImageBufAlgo::computePixelStats(one).nancount.empty());
    for (auto n : OIIO::ImageBufAlgo::computePixelStats(one).nancount)
        EXPECT_EQ(n, 0u);
}

TEST(Sure, SafetyNetFindsTheTileTheDenoiserMadeWorse)
{
    // A box blur that also adds 1 (ten standard deviations) to tile (1, 0): SURE finds that
    // tile worse than the render; with the net on it is the render there, SURE = sigma^2.
    const float variance = 0.01f;
    ImageBuf src = noisy_render(64, 64, gradient, variance, 21);
    const Denoiser blur = box_denoiser(1);
    const Denoiser biased = [&](ImageBuf& dst, const ImageBuf& in) {
        if (!blur(dst, in))
            return false;
        const ROI tile(32, 64, 0, 32, 0, 1, 0, 3);
        return OIIO::ImageBufAlgo::add(dst, dst, 1.0f, tile);
    };
    SureOptions options;
    EXPECT_TRUE(options.fallback) << "the safety net is on by default";
    options.aovs = generic_spec();
    options.output_fallback = true;
    options.fallback = false;
    const ImageBuf kept = sure(src, biased, options);
    ASSERT_FALSE(kept.has_error()) << kept.geterror();
    EXPECT_EQ(kept.spec().get_int_attribute(kSureWorseCountAttribute), 1);
    EXPECT_EQ(kept.spec().get_int_attribute(kSureFallbackCountAttribute), 0);
    options.fallback = true;
    const ImageBuf net = sure(src, biased, options);
    ASSERT_FALSE(net.has_error()) << net.geterror();
    EXPECT_EQ(net.spec().get_int_attribute(kSureFallbackCountAttribute), 1);
    const int flag = channel(net, sure_channels::kFallback);
    const int estimate = channel(net, "sure.G");
    for (int y : { 5, 40 })
        for (int x : { 5, 40 }) {
            const bool worse = x >= 32 && y < 32;
            EXPECT_EQ(net.getchannel(x, y, 0, flag), worse ? 1.0f : 0.0f) << x << "," << y;
            EXPECT_EQ(kept.getchannel(x, y, 0, flag), worse ? 1.0f : 0.0f) << x << "," << y;
            if (worse) {
                EXPECT_EQ(net.getchannel(x, y, 0, 1), src.getchannel(x, y, 0, 1));
                EXPECT_FLOAT_EQ(net.getchannel(x, y, 0, estimate), variance);
                EXPECT_NEAR(kept.getchannel(x, y, 0, 1), src.getchannel(x, y, 0, 1), 2.0f);
                EXPECT_GT(kept.getchannel(x, y, 0, 1) - src.getchannel(x, y, 0, 1), 0.5f);
            } else {
                EXPECT_EQ(net.getchannel(x, y, 0, 1), kept.getchannel(x, y, 0, 1));
            }
        }
}

TEST(Sure, NeedsTheVariance)
{
    ImageBuf src = make_image(8, 8, { "R", "G", "B" }, [](int, int, int) { return 0.5f; });
    SureOptions options;
    options.aovs = generic_spec();
    ImageBuf out;
    EXPECT_FALSE(sure(out, src, box_denoiser(1), options));
    EXPECT_NE(out.geterror().find("color_variance"), std::string::npos) << out.geterror();
}
