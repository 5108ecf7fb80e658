// choose: per pixel the denoiser whose SURE, summed over a window, is lower (mcdn/choose.h).
#include "mcdn/choose.h"

#include <OpenImageIO/imagebufalgo.h>

#include "choose/half_render.h"
#include "mcdn/denoise.h"
#include "synthetic.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

float checker(int x, int y, int c)
{
    return ((x / 4 + y / 4) % 2) ? 0.8f : 0.1f + 0.05f * c;
}

const int kSize = 96;

// The truth where `left` says so (x < kSize / 2, or the other half), the render elsewhere:
// SURE there is (truth - x)^2 - Var (its derivative is 0; expected error 0) against the
// render's Var.
Denoiser half_oracle(bool left)
{
    return [left](ImageBuf& dst, const ImageBuf& src) {
        dst.copy(src, OIIO::TypeDesc::FLOAT);
        float* px = static_cast<float*>(dst.localpixels());
        const int n = dst.nchannels();
        for (int y = 0; y < kSize; ++y)
            for (int x = 0; x < kSize; ++x)
                if ((x < kSize / 2) == left)
                    for (int c = 0; c < 3; ++c)
                        px[(size_t(y) * kSize + x) * n + c] = checker(x, y, c);
        return true;
    };
}

double mse(const ImageBuf& result, ROI roi)
{
    double sum = 0;
    for (int y = roi.ybegin; y < roi.yend; ++y)
        for (int x = roi.xbegin; x < roi.xend; ++x)
            for (int c = 0; c < 3; ++c) {
                const double d = result.getchannel(x, y, 0, c) - checker(x, y, c);
                sum += d * d;
            }
    return sum / (3.0 * roi.npixels());
}

// The render with sure's channels after `denoiser`, as the chain hands it to choose.
ImageBuf after_sure(const ImageBuf& render, const Denoiser& denoiser)
{
    SureOptions options;
    options.aovs = generic_spec();
    options.fallback = false;
    ImageBuf out;
    EXPECT_TRUE(sure(out, render, denoiser, options)) << out.geterror();
    return out;
}

}  // namespace

TEST(Choose, KeepsEachDenoiserWhereItsSureIsLower)
{
    const float variance = 0.01f;
    const ImageBuf render = noisy_render(kSize, kSize, checker, variance, 7);
    const ImageBuf a = after_sure(render, half_oracle(true));
    ChooseOptions options;
    options.aovs = generic_spec();
    options.output_weight = true;
    ImageBuf out;
    ASSERT_TRUE(choose(out, a, half_oracle(false), options)) << out.geterror();
    const int weight = out.spec().channelindex("choose.weight");
    ASSERT_GE(weight, 0);
    // Away from the seam (the window and the smoothing reach 12 pixels), each side is its
    // oracle: b's share of the inverse errors is small where b's error is the render's.
    const ROI left(0, kSize / 2 - 13, 0, kSize), right(kSize / 2 + 13, kSize, 0, kSize);
    const auto weights_left = OIIO::ImageBufAlgo::computePixelStats(out, left);
    const auto weights_right = OIIO::ImageBufAlgo::computePixelStats(out, right);
    EXPECT_LT(weights_left.avg[weight], 0.05);
    EXPECT_GT(weights_right.avg[weight], 0.95);
    // Either denoiser alone leaves the render's error on half the frame.
    const ROI all(0, kSize, 0, kSize);
    EXPECT_LT(mse(out, left), 0.05 * mse(a, right));
    EXPECT_LT(mse(out, right), 0.05 * mse(a, right));
    EXPECT_LT(mse(out, all), 0.1 * mse(a, all));
    EXPECT_NEAR(out.spec().get_float_attribute(kChooseShareAttribute), 0.5, 0.05);
    // Its SURE is the chosen image's: residual against the render, and the sum of terms.
    const int x = out.spec().channelindex("noisy.G"), s = out.spec().channelindex("sure.G"),
              r = out.spec().channelindex("sure.residual.G"),
              d = out.spec().channelindex("sure.divergence.G");
    for (int y = 0; y < kSize; y += 7)
        for (int px = 0; px < kSize; px += 5) {
            const float e = out.getchannel(px, y, 0, 1) - out.getchannel(px, y, 0, x);
            EXPECT_NEAR(out.getchannel(px, y, 0, r), e * e, 1e-6f);
            EXPECT_NEAR(out.getchannel(px, y, 0, s),
                        out.getchannel(px, y, 0, r) + 2 * out.getchannel(px, y, 0, d) - variance,
                        1e-5f);
        }
}

// max_noise: the other denoiser weighs only where the render's relative variance, over the
// window, is below it, and is not run where it weighs nowhere.
TEST(Choose, WeighsTheOtherOnlyWhereTheRenderIsCleanEnough)
{
    const ImageBuf render = noisy_render(kSize, kSize, checker, 0.01f, 7);
    ImageBuf a = after_sure(render, half_oracle(true));
    // The right half's variance a ten-thousandth of the left's: Var / (y^2 + 0.01) is below
    // 1e-4 there and 0.01-0.5 on the left.
    const int variance = a.spec().channelindex("variance.R");
    ASSERT_GE(variance, 0);
    const ROI right_half(kSize / 2, kSize, 0, kSize, 0, 1, variance, variance + 3);
    ASSERT_TRUE(OIIO::ImageBufAlgo::mul(a, a, 1e-4f, right_half));
    ChooseOptions options;
    options.aovs = generic_spec();
    options.output_weight = true;
    options.max_noise = 0.005f;
    int runs = 0;
    const Denoiser right_oracle = half_oracle(false);
    const Denoiser counted = [&](ImageBuf& dst, const ImageBuf& src) {
        ++runs;
        return right_oracle(dst, src);
    };
    ImageBuf out;
    ASSERT_TRUE(choose(out, a, counted, options)) << out.geterror();
    EXPECT_EQ(runs, 2);  // its result and one probe
    const int weight = out.spec().channelindex("choose.weight");
    const ROI left(0, kSize / 2 - 13, 0, kSize), right(kSize / 2 + 13, kSize, 0, kSize);
    EXPECT_EQ(OIIO::ImageBufAlgo::computePixelStats(out, left).max[weight], 0.0);
    EXPECT_GT(OIIO::ImageBufAlgo::computePixelStats(out, right).avg[weight], 0.5);
    // Noisier than the bound everywhere: not run, the image before as it was.
    options.max_noise = 1e-6f;
    ImageBuf kept;
    ASSERT_TRUE(choose(kept, a, counted, options)) << kept.geterror();
    EXPECT_EQ(runs, 2);
    EXPECT_EQ(kept.spec().get_float_attribute(kChooseShareAttribute, -1), 0.0f);
    EXPECT_EQ(
        OIIO::ImageBufAlgo::computePixelStats(kept).max[kept.spec().channelindex("choose.weight")],
        0.0);
    const int n = a.nchannels();
    EXPECT_EQ(
        OIIO::ImageBufAlgo::compare(OIIO::ImageBufAlgo::channels(kept, n, {}), a, 0, 0).maxerror,
        0.0);
}

TEST(Choose, SameBitsForAnyThreadsAndInPlace)
{
    const ImageBuf render = noisy_render(kSize, kSize, checker, 0.02f, 11);
    ImageBuf a = after_sure(render, box_denoiser(2));
    ChooseOptions options;
    options.aovs = generic_spec();
    ImageBuf one, two;
    ASSERT_TRUE(choose(one, a, box_denoiser(4), options, {}, 1)) << one.geterror();
    ASSERT_TRUE(choose(two, a, box_denoiser(4), options, {}, 2)) << two.geterror();
    // In place with the other denoiser run in the rebuilt render itself (as a network's is:
    // b is then that frame), and with a result of its own: the same bits, src untouched.
    ImageBuf in_render;
    in_render.copy(a);
    ChooseOptions probed_in_place = options;
    probed_in_place.sure.denoiser_in_place = true;
    ASSERT_TRUE(choose(in_render, in_render, box_denoiser(4), probed_in_place, {}, 2))
        << in_render.geterror();
    ImageBuf separate;
    ASSERT_TRUE(choose(separate, a, box_denoiser(4), probed_in_place, {}, 2))
        << separate.geterror();
    ImageBuf a_before;
    a_before.copy(a);
    ASSERT_TRUE(choose(a, a, box_denoiser(4), options, {}, 2)) << a.geterror();
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, two, 0, 0).nfail, 0u);
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, a, 0, 0).nfail, 0u);
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, in_render, 0, 0).nfail, 0u);
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, separate, 0, 0).nfail, 0u);
    EXPECT_EQ(one.spec().channelnames, in_render.spec().channelnames);
    ImageBuf again;
    ASSERT_TRUE(choose(again, a_before, box_denoiser(4), options, {}, 2));
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, again, 0, 0).nfail, 0u);  // a_before untouched
}

// A box blur of the colour (channels 0-2), for renders with or without halves.
Denoiser colour_box(int radius)
{
    return [radius](ImageBuf& dst, const ImageBuf& src) {
        const int size = 2 * radius + 1;
        const ImageBuf blurred =
            OIIO::ImageBufAlgo::convolve(OIIO::ImageBufAlgo::channels(src, 3, { 0, 1, 2 }),
                                         OIIO::ImageBufAlgo::make_kernel("box", size, size));
        ImageBuf out;
        out.copy(src, OIIO::TypeDesc::FLOAT);
        OIIO::ImageBufAlgo::paste(out, 0, 0, 0, 0, blurred);
        dst = std::move(out);  // dst may be src
        return true;
    };
}

// The halves' rule (ChooseEstimate::Halves): each denoiser on each half, the other half the
// target. Where a is the truth, b's least-squares weight is noise about 0 and never
// significant; where b is, about 1.
TEST(Choose, HalvesKeepEachDenoiserWhereItsErrorIsLower)
{
    const ImageBuf render = noisy_render(kSize, kSize, checker, 0.01f, 7);
    const ImageBuf a = after_sure(render, half_oracle(true));
    int before_runs = 0, other_runs = 0;
    const Denoiser left = half_oracle(true), right = half_oracle(false);
    ChooseOptions options;
    options.aovs = generic_spec();
    options.output_weight = true;
    options.estimate = ChooseEstimate::Halves;
    options.before = [&](ImageBuf& dst, const ImageBuf& src) {
        ++before_runs;
        EXPECT_LT(src.spec().channelindex("A.R"), 0);  // a render of its own: no halves
        EXPECT_LT(src.spec().channelindex("noisy.R"), 0);
        return left(dst, src);
    };
    const Denoiser other = [&](ImageBuf& dst, const ImageBuf& src) {
        ++other_runs;
        return right(dst, src);
    };
    ImageBuf out;
    ASSERT_TRUE(choose(out, a, other, options)) << out.geterror();
    EXPECT_EQ(before_runs, 2);  // half A, half B
    EXPECT_EQ(other_runs, 4);   // the halves, its result and one probe
    EXPECT_EQ(out.spec().get_string_attribute(kChooseEstimateAttribute), "halves");
    const int weight = out.spec().channelindex("choose.weight");
    const ROI left_side(0, kSize / 2 - 13, 0, kSize), right_side(kSize / 2 + 13, kSize, 0, kSize);
    EXPECT_LT(OIIO::ImageBufAlgo::computePixelStats(out, left_side).avg[weight], 0.05);
    EXPECT_GT(OIIO::ImageBufAlgo::computePixelStats(out, right_side).avg[weight], 0.9);
    EXPECT_LT(mse(out, right_side), 0.1 * mse(a, right_side));
    // Without the denoiser before, SURE weighs, and says why.
    options.before = {};
    ASSERT_TRUE(choose(out, a, other, options)) << out.geterror();
    EXPECT_EQ(out.spec().get_string_attribute(kChooseEstimateAttribute),
              "SURE (no denoiser before it was given)");
}

TEST(Choose, HalvesSameBitsForAnyThreadsAndInPlace)
{
    const ImageBuf render = noisy_render(kSize, kSize, checker, 0.02f, 11);
    ImageBuf a = after_sure(render, colour_box(1));
    ChooseOptions options;
    options.aovs = generic_spec();
    options.estimate = ChooseEstimate::Halves;
    options.before = colour_box(1);
    options.output_weight = true;
    ImageBuf one, two;
    ASSERT_TRUE(choose(one, a, colour_box(3), options, {}, 1)) << one.geterror();
    ASSERT_TRUE(choose(two, a, colour_box(3), options, {}, 2)) << two.geterror();
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, two, 0, 0).nfail, 0u);
    // No worse than the better of the two blurs (the narrow keeps the checker's edges, the
    // wide is smoother inside its squares).
    const ROI all(0, kSize, 0, kSize);
    ImageBuf b;
    ASSERT_TRUE(colour_box(3)(b, render));
    EXPECT_LE(mse(one, all), 1.02 * std::min(mse(a, all), mse(b, all)));
    ASSERT_TRUE(choose(a, a, colour_box(3), options, {}, 2)) << a.geterror();
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(one, a, 0, 0).nfail, 0u);
}

// A half of the render as a render of its own: its colour is the half's, its variance
// twice the render's (half the samples), and no half or sure channel is left.
TEST(Choose, HalfRenderIsOneHalfWithItsOwnVariance)
{
    const ImageBuf render = noisy_render(16, 16, checker, 0.01f, 5);
    const ImageBuf a = after_sure(render, colour_box(1));
    AovSet aovs;
    std::string error;
    ASSERT_TRUE(resolve_aovs(aovs, generic_spec(), a.spec(), error)) << error;
    ImageBuf half;
    ASSERT_TRUE(half_render(half, a, aovs, Face::HalfB, 2, error)) << error;
    EXPECT_EQ(half.spec().channelnames, (std::vector<std::string> { "R", "G", "B", "variance.R",
                                                                    "variance.G", "variance.B" }));
    for (int c = 0; c < 3; ++c) {
        EXPECT_EQ(half.getchannel(3, 4, 0, c), render.getchannel(3, 4, 0, 9 + c));
        EXPECT_FLOAT_EQ(half.getchannel(3, 4, 0, 3 + c), 0.02f);
    }
    const ImageBuf no_halves = OIIO::ImageBufAlgo::channels(render, 6, { 0, 1, 2, 3, 4, 5 });
    ASSERT_TRUE(resolve_aovs(aovs, generic_spec(), no_halves.spec(), error)) << error;
    EXPECT_FALSE(half_render(half, no_halves, aovs, Face::HalfA, 1, error));
    EXPECT_NE(error.find("half buffers"), std::string::npos) << error;
}

TEST(Choose, WithoutSureOrHalvesItSaysWhatIsMissing)
{
    const ImageBuf render = noisy_render(32, 32, checker, 0.01f, 3);
    ChooseOptions options;
    options.aovs = generic_spec();
    ImageBuf out;
    EXPECT_FALSE(choose(out, render, box_denoiser(1), options));
    EXPECT_NE(out.geterror().find("--sure"), std::string::npos) << out.geterror();
    // Without half buffers NFOR would run another path than the one choose is made for.
    const ImageBuf a = after_sure(render, box_denoiser(1));
    std::vector<int> kept;
    for (int c = 0; c < a.nchannels(); ++c)
        if (a.spec().channelnames[c].compare(0, 2, "A.") != 0
            && a.spec().channelnames[c].compare(0, 2, "B.") != 0)
            kept.push_back(c);
    const ImageBuf no_halves = OIIO::ImageBufAlgo::channels(a, int(kept.size()), kept);
    options.other_needs_halves = true;  // as the stage's NFOR (with=nfor)
    EXPECT_FALSE(choose(out, no_halves, box_denoiser(1), options));
    EXPECT_NE(out.geterror().find("half buffers"), std::string::npos) << out.geterror();
}

TEST(Choose, DenoisePlansItWhereTheRenderHasHalves)
{
    const ImageBuf render = noisy_render(32, 32, checker, 0.01f, 3);
    DenoisePlan plan;
    std::string error;
    // Our CNN's plan, whatever OIDN weights this machine has.
    const std::map<std::string, std::string> cnn = { { "oidn.weights", "/nonexistent" } };
    ASSERT_TRUE(plan_denoise(plan, render.spec(), generic_spec(), error, cnn)) << error;
    EXPECT_EQ(plan.stages, (std::vector<std::string> { "cnn", "sure", "choose", "mix" }));
    ASSERT_TRUE(plan_denoise(plan, render.spec(), generic_spec(), error,
                             { { "oidn.weights", "/nonexistent" }, { "denoise.choose", "0" } }));
    EXPECT_EQ(plan.stages, (std::vector<std::string> { "cnn", "sure", "mix" }));
    // Without halves there is no NFOR to choose.
    const ImageBuf no_halves = OIIO::ImageBufAlgo::channels(render, 6, { 0, 1, 2, 3, 4, 5 });
    ASSERT_TRUE(plan_denoise(plan, no_halves.spec(), generic_spec(), error, cnn)) << error;
    EXPECT_EQ(plan.stages, (std::vector<std::string> { "cnn", "sure", "mix" }));
    // Cross-frame, the CNN's neighbours are against flicker: NFOR would be one frame's.
    ASSERT_TRUE(plan_denoise(plan, render.spec(), generic_spec(), error,
                             { { "oidn.weights", "/nonexistent" }, { "denoise.frames", "2" } }));
    EXPECT_EQ(plan.stages, (std::vector<std::string> { "cnn", "sure", "mix" }));
}

// mcdntool -v says how much of the result is NFOR's, once, streamed or stage by stage.
TEST(Choose, VerboseSaysNforsShareOnce)
{
    const std::string dir = mcdn_test::temp_dir("choose_verbose");
    const std::string box = test_data("box16/box_0016spp");
    const std::string inputs = "-v -i " + box + ".exr -i:as=variance " + box
                               + "_var.exr -i:as=halfA " + box + "_A.exr -i:as=halfB " + box
                               + "_B.exr ";
    for (const std::string& chain :
         { std::string("--denoise"), std::string("--cnn --sure --choose --fixnan black --mix") }) {
        const auto run = run_mcdntool(inputs + chain + " -o " + dir + "/out.exr",
                                      "MCDN_OIDN_WEIGHTS=/nonexistent");
        ASSERT_EQ(run.exit_code, 0) << run.output;
        const std::string line = "choose: the second denoiser's weight (with=) averages ";
        const size_t at = run.output.find(line);
        ASSERT_NE(at, std::string::npos) << chain << "\n" << run.output;
        EXPECT_EQ(run.output.find(line, at + 1), std::string::npos) << chain << "\n" << run.output;
    }
}
