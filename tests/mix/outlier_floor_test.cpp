// The outlier floor of the mix model's alpha (lib/src/mix/outlier_floor.cpp): where the render
// pixel is an outlier of its own variance, alpha >= the pixel's PD eq. 9 (alpha = 1 where
// the variance is larger still); nowhere else.
#include <cmath>
#include <limits>

#include "mix/mix_steps.h"

#include <gtest/gtest.h>

using namespace mcdn;

namespace {

// A flat 0.5 image with a render firefly of `spike` at (8, 8) whose variance says so (one
// sample of ~16 x spike among 16: Var of the mean ~ spike^2), and a network alpha of `net`.
struct Scene {
    Plane alpha, x, y, variance, divergence, residual;
    Scene(float net, float spike, float spike_variance)
        : alpha(16, 16, net), x(16, 16, 0.5f), y(16, 16, 0.5f), variance(16, 16, 1e-3f),
          divergence(16, 16, 1e-4f), residual(16, 16, 0.0f)
    {
        x(8, 8) = spike;
        variance(8, 8) = spike_variance;
        divergence(8, 8) = 0.02f * spike_variance;
        for (size_t i = 0; i < x.size(); ++i)
            residual.px[i] = (y.px[i] - x.px[i]) * (y.px[i] - x.px[i]);
    }
    // The eq. 9 rule alone by default (drop 0): the tests of the drop rule say so.
    void apply(float threshold = 10.0f, float drop = 0.0f)
    {
        outlier_floor(alpha, variance, y, divergence, residual, threshold, drop);
    }
};

}  // namespace

TEST(MixOutlierFloor, AFireflyTheNetworkKeptGoesToTheDenoised)
{
    // As small/0001_exterior at 16 spp (x = 47, y = 0.69, Var = 2159, sigma^2 f' = 49, eq. 9
    // = 1.0): here ||y - x||^2 = 2162, Var = 2300, sigma^2 f' = 46 -> eq. 9 = 1.04, clipped.
    Scene s(0.0f, 47.0f, 2300.0f);
    s.apply();
    EXPECT_NEAR(s.alpha(8, 8), 1.0f, 1e-6);
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
            if (x != 8 || y != 8) {
                EXPECT_EQ(s.alpha(x, y), 0.0f) << x << "," << y;  // ordinary pixels untouched
            }
        }
}

TEST(MixOutlierFloor, NeverLowersAlpha)
{
    Scene s(0.8f, 47.0f, 2300.0f);
    s.apply();
    EXPECT_NEAR(s.alpha(8, 8), 1.0f, 1e-6);
    Scene low_eq9(0.8f, 47.0f, 300.0f);  // eq. 9 = (300 - 6) / 2162 = 0.14 < 0.8
    low_eq9.apply();
    EXPECT_EQ(low_eq9.alpha(8, 8), 0.8f);
}

TEST(MixOutlierFloor, ABrightFeatureTheDenoiserBlurredKeepsTheRender)
{
    // The same bright pixel with a variance that explains only a little of ||y - x||^2: the
    // denoiser is biased there, eq. 9 is small, and the network's alpha = 0 stays near 0.
    Scene s(0.0f, 47.0f, 100.0f);
    s.apply();
    EXPECT_NEAR(s.alpha(8, 8), (100.0f - 2.0f) / (46.5f * 46.5f), 1e-4);
    EXPECT_LT(s.alpha(8, 8), 0.05f);
}

TEST(MixOutlierFloor, SwitchesOffAsTheVarianceFalls)
{
    // Relative variance below the threshold (here 2 / (0.25 + 0.01) = 7.7 < 10): untouched,
    // so the floor cannot stop the mix from converging to the render; threshold 0: never.
    Scene s(0.0f, 3.0f, 2.0f);
    s.apply();
    EXPECT_EQ(s.alpha(8, 8), 0.0f);
    Scene off(0.0f, 47.0f, 2159.0f);
    off.apply(std::numeric_limits<float>::infinity());
    EXPECT_EQ(off.alpha(8, 8), 0.0f);
}

TEST(MixOutlierFloor, NonFiniteInputsLeaveAlphaAlone)
{
    Scene s(0.3f, 47.0f, 2159.0f);
    s.divergence(8, 8) = std::numeric_limits<float>::quiet_NaN();
    s.variance(9, 9) = std::numeric_limits<float>::infinity();
    s.residual(10, 10) = 0.0f;
    s.variance(10, 10) = 1e6f;
    s.apply();
    for (float a : s.alpha.px)
        EXPECT_TRUE(std::isfinite(a));
    EXPECT_EQ(s.alpha(8, 8), 0.3f);
    EXPECT_EQ(s.alpha(10, 10), 0.3f);
}

TEST(MixOutlierFloor, ANoisyDivergenceDoesNotKeepAFirefly)
{
    // As 0040_metal at 256 spp (x = 98, y = 9.0, Var = 9583, ||y - x||^2 = 7942, one-probe
    // sigma^2 f'(x) = 31030, i.e. f' = 3.2): eq. 9 is negative and kept the firefly; past
    // the drop threshold (Var > 3 (y^2 + 0.01)) alpha = 1, and the t-test keeps it there
    // (the deviation is within the pixel's own noise: t ~ 0.9).
    Scene s(0.0f, 98.0f, 9583.0f);
    s.y(8, 8) = 9.0f;
    s.residual(8, 8) = 89.0f * 89.0f;
    s.divergence(8, 8) = 31030.0f;
    s.apply(0.3f, 0.0f);
    EXPECT_EQ(s.alpha(8, 8), 0.0f);
    s.apply(0.3f, 3.0f);
    EXPECT_EQ(s.alpha(8, 8), 1.0f);
    t_test_bound(s.alpha, s.x, s.y, s.variance, 100.0f, MixOptions());
    EXPECT_GT(s.alpha(8, 8), 0.99f);
}

TEST(MixOutlierFloor, ABrightFeatureTheRenderResolvesIsTheTTestsCase)
{
    // The bright feature of ABrightFeatureTheDenoiserBlurredKeepsTheRender is past the drop
    // threshold too (Var 100 over y^2 + 0.01 = 0.26), so the floor gives it alpha = 1; but its
    // deviation is 4.65 standard errors, and the t-test (the pixel is its own highest-
    // variance neighbour) takes alpha' back toward the render: (1 - Phi(2 (4.67 - 4.2))).
    Scene s(0.0f, 47.0f, 100.0f);
    s.apply(0.3f, 3.0f);
    EXPECT_EQ(s.alpha(8, 8), 1.0f);
    t_test_bound(s.alpha, s.x, s.y, s.variance, 100.0f, MixOptions());
    EXPECT_LT(s.alpha(8, 8), 0.25f);
    // Between the two thresholds eq. 9 is the bound, with its divergence term.
    Scene mid(0.0f, 47.0f, 100.0f);
    mid.y.px.assign(mid.y.size(), 10.0f);  // y^2 + 0.01 = 100: relative variance 1
    for (size_t i = 0; i < mid.x.size(); ++i)
        mid.residual.px[i] = (mid.y.px[i] - mid.x.px[i]) * (mid.y.px[i] - mid.x.px[i]);
    mid.apply(0.3f, 3.0f);
    EXPECT_NEAR(mid.alpha(8, 8), (100.0f - 2.0f) / (37.0f * 37.0f), 1e-4);
}

TEST(MixOutlierFloor, TheAnalyticModelGetsItToo)
{
    // Eq. 9 on 21x21 box averages spreads the firefly's sigma^2 and ||y - x||^2 over its
    // neighbours, where y = x. With the floor (the defaults) the firefly goes to the denoised
    // image, with it off its alpha is the box's; ordinary pixels keep the box's either way.
    MixInputs in;
    for (int c = 0; c < 3; ++c) {
        Scene s(0.0f, 47.0f, 2300.0f);
        s.divergence(8, 8) = 2000.0f;  // a denoiser that follows the spike: eq. 9's box small
        in.x[c] = s.x;
        in.y[c] = s.y;
        in.variance[c] = s.variance;
        in.divergence[c] = s.divergence;
        in.residual[c] = s.residual;
        in.sure[c] = Plane(16, 16, 0.0f);
    }
    MixOptions options;
    options.model = MixOptions::Model::Analytic;
    options.t_test = false;
    options.skip.enabled = false;
    Plane alpha[3];
    ConvergedTiles passed;
    std::string error;
    ASSERT_TRUE(mix_alpha(alpha, passed, in, options, nullptr, 1.0f, error)) << error;
    EXPECT_EQ(alpha[1](8, 8), 1.0f);  // past the drop threshold: dropped
    options.outlier_relative_variance = 0;
    options.drop_relative_variance = 0;
    Plane box[3];
    ASSERT_TRUE(mix_alpha(box, passed, in, options, nullptr, 1.0f, error)) << error;
    EXPECT_LT(box[1](8, 8), 0.2f);  // the box's: the firefly kept
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x)
            if (x != 8 || y != 8) {
                EXPECT_EQ(alpha[1](x, y), box[1](x, y)) << x << "," << y;
            }
}
