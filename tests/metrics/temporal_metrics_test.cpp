// Temporal metrics (flicker): an error that moves with the picture counts 0, noise drawn
// anew each frame about twice its per-frame MSE, and without motion compensation a moving
// picture's steady error is counted as flicker.
#include "mcdn/metrics.h"

#include <cmath>
#include <random>

#include "mcdn_test.h"

using namespace mcdn;
using mcdn_test::make_image;

namespace {

constexpr int kW = 64, kH = 48, kShift = 3;  // the picture moves 3 px right per frame

float picture(int x, int y, int c)
{
    return 0.5f + 0.4f * std::sin(0.21f * x + 0.1f * c) * std::cos(0.17f * y);
}
float steady_error(int x, int y, int c)
{
    return 0.05f * std::sin(1.3f * x + 2.1f * y + c);
}

// Frame t: the picture and an error pattern, both moved by t * kShift px.
ImageBuf frame(int t, bool with_error)
{
    return make_image(kW, kH, { "R", "G", "B" }, [=](int x, int y, int c) {
        const int u = x - t * kShift;
        return picture(u, y, c) + (with_error ? steady_error(u, y, c) : 0.0f);
    });
}

// Noise drawn anew for frame `seed`, sigma 0.05.
ImageBuf noisy(const ImageBuf& clean, unsigned seed)
{
    std::mt19937 rng(seed);
    std::normal_distribution<float> n(0.0f, 0.05f);
    ImageBuf out = clean.copy(OIIO::TypeDesc::FLOAT);
    for (int y = 0; y < kH; ++y)
        for (int x = 0; x < kW; ++x)
            for (int c = 0; c < 3; ++c) {
                float v[3];
                out.getpixel(x, y, v, 3);
                v[c] += n(rng);
                out.setpixel(x, y, v, 3);
            }
    return out;
}

// Pixel p of frame t was at p - (kShift, 0) in frame t-1.
ImageBuf motion()
{
    return make_image(kW, kH, { "X", "Y" },
                      [](int, int, int c) { return c == 0 ? -float(kShift) : 0.0f; });
}

TemporalMetrics temporal(const ImageBuf& x1, const ImageBuf& x0, const ImageBuf& r1,
                         const ImageBuf& r0, const ImageBuf* m)
{
    TemporalMetrics t;
    std::string error;
    EXPECT_TRUE(compute_temporal_metrics(t, x1, x0, r1, r0, m, TemporalOptions(), error)) << error;
    return t;
}

}  // namespace

TEST(TemporalMetrics, AnErrorThatMovesWithThePictureDoesNotFlicker)
{
    const ImageBuf m = motion();
    const TemporalMetrics t =
        temporal(frame(1, true), frame(0, true), frame(1, false), frame(0, false), &m);
    EXPECT_LT(t.mse, 1e-12);
    // The first kShift columns came from outside frame 0.
    EXPECT_EQ(t.pixels, (kW - kShift) * kH);
    // Its per-frame error is not 0: the metric tells the two apart.
    Metrics per_frame;
    std::string error;
    ASSERT_TRUE(compute_metrics(per_frame, frame(1, true), frame(1, false), {}, error));
    EXPECT_GT(per_frame.mse, 1e-4);
}

TEST(TemporalMetrics, NoiseDrawnAnewEachFrameCountsTwiceItsMse)
{
    const ImageBuf m = motion();
    const ImageBuf r0 = frame(0, false), r1 = frame(1, false);
    const TemporalMetrics t = temporal(noisy(r1, 1), noisy(r0, 2), r1, r0, &m);
    EXPECT_NEAR(t.mse, 2 * 0.05 * 0.05, 0.1 * 2 * 0.05 * 0.05);
    EXPECT_GT(t.relmse, t.mse);  // values below 1: relMSE's denominator is below 1
}

TEST(TemporalMetrics, WithoutMotionCompensationAMovingErrorCounts)
{
    const TemporalMetrics t =
        temporal(frame(1, true), frame(0, true), frame(1, false), frame(0, false), nullptr);
    EXPECT_GT(t.mse, 1e-4);
    EXPECT_EQ(t.pixels, kW * kH);
}

TEST(TemporalMetrics, MismatchedOrNonFiniteInputsAreErrors)
{
    TemporalMetrics t;
    std::string error;
    const ImageBuf small = make_image(8, 8, { "R", "G", "B" }, [](int, int, int) { return 0.5f; });
    EXPECT_FALSE(compute_temporal_metrics(t, frame(1, false), small, frame(1, false), small,
                                          nullptr, TemporalOptions(), error));
    const ImageBuf bad =
        make_image(kW, kH, { "X", "Y" }, [](int x, int, int) { return x == 5 ? NAN : 0.0f; });
    EXPECT_FALSE(compute_temporal_metrics(t, frame(1, false), frame(0, false), frame(1, false),
                                          frame(0, false), &bad, TemporalOptions(), error));
    EXPECT_NE(error.find("'X'"), std::string::npos) << error;
}

TEST(TemporalMetrics, AReferenceNoiseIsWhatItsVarianceSays)
{
    // A perfect image against references that are renders themselves (noise of variance v):
    // all the error measured is the references' noise, which ReferenceNoise predicts from
    // their variance. With a half-pixel motion the warp averages two pixels of frame t-1,
    // whose noise then counts v / 2.
    const float v = 0.05f * 0.05f;
    const ImageBuf r0 = frame(0, false), r1 = frame(1, false);
    const ImageBuf n0 = noisy(r0, 3), n1 = noisy(r1, 4);
    const ImageBuf var = make_image(kW, kH, { "R", "G", "B" }, [=](int, int, int) { return v; });
    const ImageBuf half =
        make_image(kW, kH, { "X", "Y" }, [](int, int, int c) { return c == 0 ? -2.5f : 0.0f; });
    Metrics m;
    ReferenceNoise noise;
    std::string error;
    ASSERT_TRUE(compute_metrics(m, r1, n1, {}, error)) << error;
    ASSERT_TRUE(compute_reference_noise(noise, n1, var, {}, error)) << error;
    EXPECT_NEAR(noise.mse, v, 1e-9);
    EXPECT_NEAR(m.mse, noise.mse, 0.1 * v);
    EXPECT_NEAR(m.relmse, noise.relmse, 0.1 * noise.relmse);

    const TemporalMetrics t = temporal(r1, r0, n1, n0, &half);
    ASSERT_TRUE(compute_temporal_reference_noise(noise, n1, var, var, &half, {}, error)) << error;
    EXPECT_NEAR(noise.mse, 1.5 * v, 1e-9);
    EXPECT_NEAR(t.mse, noise.mse, 0.1 * noise.mse);
    EXPECT_NEAR(t.relmse, noise.relmse, 0.1 * noise.relmse);

    // Without the motion the warp takes one pixel: v + v.
    ASSERT_TRUE(compute_temporal_reference_noise(noise, n1, var, var, nullptr, {}, error)) << error;
    EXPECT_NEAR(noise.mse, 2 * v, 1e-9);
    // A variance of another size is an error.
    const ImageBuf small = make_image(8, 8, { "R", "G", "B" }, [=](int, int, int) { return v; });
    EXPECT_FALSE(compute_reference_noise(noise, n1, small, {}, error));
    EXPECT_FALSE(compute_temporal_reference_noise(noise, n1, var, small, nullptr, {}, error));
}
