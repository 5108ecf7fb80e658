// The progressive mix: better than either input where it should be, and converging to the
// render as the variance falls (PD §4).
#include "mcdn/mix.h"

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/sure.h"
#include "mix/mix_steps.h"

#include "synthetic.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

float checker(int x, int y, int c)
{
    return ((x / 3 + y / 3) % 2) ? 0.9f : 0.1f + 0.05f * c;
}
float smooth(int x, int y, int c)
{
    return 0.3f + 0.002f * x + 0.001f * y + 0.05f * c;
}

double mse(const ImageBuf& a, const ImageBuf& truth)
{
    auto comp =
        OIIO::ImageBufAlgo::compare(OIIO::ImageBufAlgo::channels(a, 3, { 0, 1, 2 }), truth, 0, 0);
    return comp.rms_error * comp.rms_error;
}

struct Outcome {
    double render, denoised, mixed, alpha;
};

Outcome run(float (*truth)(int, int, int), float variance, MixOptions options = {})
{
    const int n = 96;
    ImageBuf src = noisy_render(n, n, truth, variance, 11);
    SureOptions so;
    so.aovs = generic_spec();
    ImageBuf with_sure;
    EXPECT_TRUE(sure(with_sure, src, box_denoiser(2), so)) << with_sure.geterror();
    options.aovs = generic_spec();
    options.output_alpha = true;
    ImageBuf z;
    EXPECT_TRUE(mix(z, with_sure, options)) << z.geterror();
    ImageBuf t = truth_image(n, n, truth);
    int a = z.spec().channelindex("mix.alpha.G");
    return { mse(src, t), mse(with_sure, t), mse(z, t), channel_mean(z, a) };
}

}  // namespace

TEST(Mix, NoisyRenderOfASmoothImageTrustsTheDenoiser)
{
    // The analytic model's alpha carries the noise of its 21x21 averages (about 7%), which
    // costs a few percent of MSE where the denoiser is near perfect.
    for (float variance : { 5e-2f, 1e-3f, 1e-5f }) {
        Outcome o = run(smooth, variance);
        EXPECT_LT(o.denoised, 0.2 * o.render);
        EXPECT_GT(o.alpha, 0.9);
        EXPECT_LE(o.mixed, o.denoised * 1.10) << variance;
    }
}

TEST(Mix, ConvergesToTheRenderWhereTheDenoiserIsBiased)
{
    // The box blur smears the checker: its bias dominates once the variance is small.
    double previous_alpha = 2;
    for (float variance : { 1e-2f, 1e-3f, 1e-4f, 1e-5f }) {
        Outcome o = run(checker, variance);
        EXPECT_LE(o.mixed, std::min(o.render, o.denoised) * 1.02 + 1e-9) << variance;
        EXPECT_LT(o.alpha, previous_alpha + 1e-6) << variance;
        previous_alpha = o.alpha;
    }
    Outcome converged = run(checker, 1e-6f);
    EXPECT_LT(converged.alpha, 0.02);
    EXPECT_NEAR(converged.mixed, converged.render, 0.05 * converged.render);
}

TEST(Mix, TTestOnlyEverLowersAlpha)
{
    MixOptions without;
    without.t_test = false;
    for (float variance : { 1e-2f, 1e-4f }) {
        Outcome free = run(checker, variance, without), bounded = run(checker, variance);
        EXPECT_LE(bounded.alpha, free.alpha);
        EXPECT_LE(bounded.mixed, free.mixed * 1.0001);
    }
}

TEST(MixTTest, RejectsASignificantDeviationAndKeepsANoisyOne)
{
    // alpha = 1 and y = x + 0.01 everywhere: with variance 1e-2 the offset is noise-sized
    // (|t| well below c = 4.2, alpha kept); with variance 1e-8 it is thousands of standard
    // deviations (alpha' -> 0). Eq. 18.
    MixOptions options;
    for (auto [variance, expected] : { std::pair { 1e-2f, 1.0f }, std::pair { 1e-8f, 0.0f } }) {
        Plane alpha(32, 32, 1.0f), x(32, 32, 0.5f), y(32, 32, 0.51f), var(32, 32, variance);
        t_test_bound(alpha, x, y, var, 10.0f, options);
        EXPECT_NEAR(alpha(16, 16), expected, 1e-3) << variance;
        EXPECT_NEAR(alpha(0, 0), expected, 1e-3) << variance;
    }
}

TEST(Mix, NeedsSureChannels)
{
    ImageBuf src = noisy_render(16, 16, smooth, 0.01f, 2);
    MixOptions options;
    options.aovs = generic_spec();
    ImageBuf out;
    EXPECT_FALSE(mix(out, src, options));
    EXPECT_NE(out.geterror().find("run --sure before it"), std::string::npos) << out.geterror();
}
