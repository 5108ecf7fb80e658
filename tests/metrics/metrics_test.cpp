// Metrics against hand-computed values, trimming, SSIM, heatmaps, and the published table.
#include "mcdn/metrics.h"

#include <cmath>

#include "mcdn/io.h"

#include "mcdn_test.h"

using namespace mcdn;
using mcdn_test::make_image;

namespace {

// A 2x1 RGB image and reference whose errors are easy to compute by hand.
ImageBuf two_pixels(float a, float b)
{
    return make_image(2, 1, { "R", "G", "B" }, [=](int x, int, int) { return x == 0 ? a : b; });
}

Metrics measure(const ImageBuf& x, const ImageBuf& r, MetricsOptions o = {})
{
    Metrics m;
    std::string error;
    EXPECT_TRUE(compute_metrics(m, x, r, o, error)) << error;
    return m;
}

}  // namespace

TEST(Metrics, MatchHandComputedValues)
{
    // x = (1.5, 0.2), r = (1.0, 0.0) on every channel
    Metrics m = measure(two_pixels(1.5f, 0.2f), two_pixels(1.0f, 0.0f));
    double se0 = 0.25, se1 = 0.04000000119;
    EXPECT_NEAR(m.mse, (se0 + se1) / 2, 1e-7);
    EXPECT_NEAR(m.rmse, std::sqrt((se0 + se1) / 2), 1e-7);
    EXPECT_NEAR(m.relmse, (se0 / 1.01 + se1 / 0.01) / 2, 1e-6);
    EXPECT_NEAR(m.smape, (0.5 / 2.51 + 0.2 / 0.21) / 2, 1e-6);
    EXPECT_NEAR(m.psnr, 10 * std::log10(1 / ((se0 + se1) / 2)), 1e-5);
    EXPECT_EQ(m.pixels, 2);
}

TEST(Metrics, IdenticalImagesArePerfect)
{
    ImageBuf r = make_image(32, 32, { "R", "G", "B" },
                            [](int x, int y, int c) { return 0.01f * ((x * 7 + y * 3 + c) % 50); });
    Metrics m = measure(r, r);
    EXPECT_EQ(m.mse, 0.0);
    EXPECT_EQ(m.relmse, 0.0);
    EXPECT_NEAR(m.ssim, 1.0, 1e-9);
    EXPECT_EQ(m.psnr, 999.0);
}

TEST(Metrics, SsimFallsWithNoise)
{
    ImageBuf r = make_image(32, 32, { "R", "G", "B" }, [](int x, int, int) { return x / 32.0f; });
    ImageBuf noisy = make_image(32, 32, { "R", "G", "B" }, [](int x, int y, int c) {
        return x / 32.0f + (((x * 31 + y * 17 + c * 7) % 11) - 5) * 0.02f;
    });
    ImageBuf very = make_image(32, 32, { "R", "G", "B" }, [](int x, int y, int c) {
        return x / 32.0f + (((x * 31 + y * 17 + c * 7) % 11) - 5) * 0.08f;
    });
    double s1 = measure(noisy, r).ssim, s2 = measure(very, r).ssim;
    EXPECT_LT(s1, 0.99);
    EXPECT_GT(s1, s2);
    EXPECT_GT(s2, 0.0);
}

TEST(Metrics, TrimDropsTheWorstAndBestPixels)
{
    // 100x100 = 10000 pixels; trim 1e-4 drops one pixel each side: the single outlier.
    ImageBuf r = make_image(100, 100, { "R", "G", "B" }, [](int, int, int) { return 1.0f; });
    ImageBuf x = make_image(100, 100, { "R", "G", "B" }, [](int px, int py, int) {
        return px == 50 && py == 50 ? 1000.0f : 1.1f;
    });
    MetricsOptions o;
    Metrics plain = measure(x, r, o);
    o.trim = true;
    Metrics trimmed = measure(x, r, o);
    EXPECT_GT(plain.mse, 10.0);
    EXPECT_NEAR(trimmed.mse, 0.01, 1e-6);
    EXPECT_EQ(trimmed.pixels, 9998);
}

TEST(Metrics, ChoosesChannelsAndRejectsBadInput)
{
    ImageBuf x = make_image(4, 4, { "R", "G", "B", "A" },
                            [](int, int, int c) { return c == 3 ? 5.0f : 1.0f; });
    ImageBuf r = make_image(4, 4, { "R", "G", "B", "A" }, [](int, int, int) { return 1.0f; });
    MetricsOptions alpha;
    alpha.image_channels = alpha.reference_channels = { 3 };
    EXPECT_NEAR(measure(x, r, alpha).mse, 16.0, 1e-9);
    EXPECT_EQ(measure(x, r).mse, 0.0);

    Metrics m;
    std::string error;
    ImageBuf small = make_image(3, 4, { "R", "G", "B" }, [](int, int, int) { return 1.0f; });
    EXPECT_FALSE(compute_metrics(m, x, small, {}, error));
    EXPECT_NE(error.find("3x4"), std::string::npos) << error;
    ImageBuf nan =
        make_image(4, 4, { "R", "G", "B" }, [](int x, int, int) { return x == 2 ? NAN : 1.0f; });
    EXPECT_FALSE(compute_metrics(m, nan, r, {}, error));
    EXPECT_NE(error.find("not finite at pixel (2, 0)"), std::string::npos) << error;
}

TEST(Metrics, HeatmapIsRgbInUnitRange)
{
    ImageBuf r = make_image(16, 8, { "R", "G", "B" }, [](int, int, int) { return 0.5f; });
    ImageBuf x =
        make_image(16, 8, { "R", "G", "B" }, [](int px, int, int) { return 0.5f + px * 0.05f; });
    ImageBuf errors, picture;
    ASSERT_TRUE(error_map(errors, x, r, {}, ErrorKind::RelMSE));
    EXPECT_EQ(errors.nchannels(), 1);
    float e[1];
    errors.getpixel(10, 3, e, 1);
    EXPECT_NEAR(e[0], 0.25 / 0.26, 1e-5);
    ASSERT_TRUE(heatmap(picture, errors)) << picture.geterror();
    EXPECT_EQ(picture.nchannels(), 3);
    float zero[3], big[3];
    picture.getpixel(0, 0, zero, 3);  // error 0: darkest colour
    picture.getpixel(15, 0, big, 3);
    EXPECT_LT(zero[0] + zero[1] + zero[2], big[0] + big[1] + big[2]);
    for (float v : big)
        EXPECT_TRUE(v >= 0.0f && v <= 1.0f);
}

TEST(Metrics, ReproduceTheSharedDataTable)
{
    MCDN_REQUIRE_SHARED(box_dir, "box");
    // ../shared/data/README.md: noisy relMSE and SMAPE of each input
    struct Row {
        std::string image, reference;
        double relmse, smape;
    };
    const Row rows[] = {
        { "box/box_0016spp.exr", "box/box_ref.exr", 0.1404, 0.1091 },
        { "box/box_0064spp.exr", "box/box_ref.exr", 0.0331, 0.0611 },
        { "box/box_0256spp.exr", "box/box_ref.exr", 0.00815, 0.0360 },
        { "box/nfor-reference/box_0016spp_nfor.exr", "box/box_ref.exr", 0.00968, 0.0334 },
        { "tungsten/cornell20/color.pfm", "tungsten/cornell20/ref.pfm", 0.01185, 0.0756 },
        { "tungsten/materialtest/color.pfm", "tungsten/materialtest/ref.pfm", 0.02466, 0.0634 },
        { "tungsten/cornell20/nfor-reference/nfor.pfm", "tungsten/cornell20/ref.pfm", 0.00075,
          0.0114 },
    };
    for (const auto& row : rows) {
        ImageBuf x, r;
        ASSERT_TRUE(read_image(x, mcdn_test::shared_data(row.image)));
        ASSERT_TRUE(read_image(r, mcdn_test::shared_data(row.reference)));
        Metrics m = measure(x, r);
        EXPECT_NEAR(m.relmse, row.relmse, row.relmse * 0.005) << row.image;
        EXPECT_NEAR(m.smape, row.smape, row.smape * 0.01) << row.image;
    }
}
