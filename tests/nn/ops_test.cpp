// Every op of the oneDNN path against the plain-loop reference (lib/src/nn/reference.cpp),
// on random inputs: 1e-5 relative.
#include <tbb/global_control.h>

#include "nn/net_plan.h"
#include "nn_test_util.h"

using namespace nn_test;

namespace {

constexpr double tolerance = 1e-5;

struct ConvCase {
    int in_channels, out_channels, kernel;
    Activation activation;
    int height, width;
};

class ConvTest : public ::testing::TestWithParam<ConvCase> { };

TEST_P(ConvTest, MatchesReference)
{
    const ConvCase c = GetParam();
    Net net("conv");
    Value x = net.input("x", c.in_channels);
    net.output("y", net.conv(x, "conv", c.out_channels, c.kernel, c.activation));
    const double error =
        onednn_vs_reference(net, { random_tensor(c.height, c.width, c.in_channels, 7) });
    EXPECT_LT(error, tolerance);
}

INSTANTIATE_TEST_SUITE_P(
    Shapes, ConvTest,
    ::testing::Values(ConvCase { 3, 48, 5, Activation::relu, 13, 17 },   // first mix layer
                      ConvCase { 48, 48, 3, Activation::relu, 16, 16 },  // residual block
                      ConvCase { 48, 48, 3, Activation::none, 9, 31 },
                      ConvCase { 48, 9, 3, Activation::none, 12, 20 },   // mix output
                      ConvCase { 27, 50, 3, Activation::relu, 10, 11 },  // not multiples of 16
                      ConvCase { 64, 441, 1, Activation::none, 6, 7 },   // 21×21 kernel head
                      ConvCase { 1, 1, 7, Activation::relu, 5, 3 }));  // image smaller than kernel

TEST(NnOps, AddWithAndWithoutRelu)
{
    for (Activation activation : { Activation::none, Activation::relu }) {
        Net net("add");
        Value a = net.input("a", 20), b = net.input("b", 20);
        net.output("y", net.add(a, b, activation));
        EXPECT_LT(
            onednn_vs_reference(net, { random_tensor(6, 9, 20, 1), random_tensor(6, 9, 20, 2) }),
            tolerance);
    }
}

TEST(NnOps, PoolUpsampleConcatSlice)
{
    Net net("shapes");
    Value x = net.input("x", 5);
    Value pooled = net.max_pool2(x);
    Value up = net.upsample2(pooled);
    net.output("pooled", pooled);
    net.output("up", up);
    net.output("concat", net.concat({ x, up, net.slice(x, 1, 3) }));
    const Tensor input = random_tensor(10, 14, 5, 3);
    EXPECT_EQ(onednn_vs_reference(net, { input }), 0.0);  // no arithmetic: exact

    std::vector<Tensor> out;
    std::string error;
    ASSERT_TRUE(net.run({ input }, out, error)) << error;
    ASSERT_EQ(out.size(), 3u);
    EXPECT_EQ(out[0].height, 5);
    EXPECT_EQ(out[0].width, 7);
    EXPECT_EQ(out[2].channels, 5 + 5 + 3);
    // Spot values, from the definitions (PyTorch max_pool2d(2), interpolate(nearest)).
    EXPECT_EQ(out[0].at(2, 3, 4), std::max({ input.at(4, 6, 4), input.at(4, 7, 4),
                                             input.at(5, 6, 4), input.at(5, 7, 4) }));
    EXPECT_EQ(out[1].at(5, 9, 2), out[0].at(2, 4, 2));
    EXPECT_EQ(out[2].at(3, 4, 10), input.at(3, 4, 1));
}

TEST(NnOps, AnUpsampleReadOnlyByAConcatIsFusedIntoIt)
{
    // A UNet decoder's step: concat(upsample2(deep), skip). The oneDNN plan has no upsample
    // step (the concat reads `deep` at half resolution) and gives the same values.
    Net net("decoder");
    Value x = net.input("x", 4);
    Value deep = net.conv(net.max_pool2(x), "deep", 6, 3);
    net.output("joined", net.concat({ net.upsample2(deep), x }));
    const Tensor input = random_tensor(8, 12, 4, 7);
    EXPECT_LT(onednn_vs_reference(net, { input }), tolerance);  // the conv's sums
    const std::vector<Step> fused = plan_steps(net.nodes(), { int(net.nodes().size()) - 1 }, true);
    EXPECT_TRUE(std::none_of(fused.begin(), fused.end(),
                             [](const Step& step) { return step.kind == Step::Kind::upsample2; }));
    const std::vector<Step> plain = plan_steps(net.nodes(), { int(net.nodes().size()) - 1 }, false);
    EXPECT_TRUE(std::any_of(plain.begin(), plain.end(),
                            [](const Step& step) { return step.kind == Step::Kind::upsample2; }));
    // Read by another node too, it is run as written.
    Net shared("shared");
    Value y = shared.input("y", 4);
    Value up = shared.upsample2(shared.max_pool2(y));
    shared.output("joined", shared.concat({ up, y }));
    shared.output("up", up);
    EXPECT_EQ(onednn_vs_reference(shared, { input }), 0.0);
}

TEST(NnOps, AConvOfAnUpsampledConcatRunsOnTheHalfResolutionInput)
{
    // A UNet decoder's conv: conv3x3(concat(upsample2(deep), skip)). The oneDNN plan makes
    // neither the upsample nor the concat (an upconv: the four output phases as one 2×2 conv
    // of `deep`, then the skip's conv summed in) and gives the reference's values, at the
    // image's border too (zero padding at both resolutions).
    for (Activation activation : { Activation::relu, Activation::none }) {
        Net net("decoder");
        Value x = net.input("x", 5);
        Value deep = net.conv(net.max_pool2(x), "deep", 7, 3);
        Value joined = net.concat({ net.upsample2(deep), x });
        net.output("out", net.conv(joined, "dec", 6, 3, activation));
        const Tensor input = random_tensor(10, 14, 5, 9);
        EXPECT_LT(onednn_vs_reference(net, { input }), tolerance);
        const std::vector<Step> fused =
            plan_steps(net.nodes(), { int(net.nodes().size()) - 1 }, true);
        EXPECT_EQ(std::count_if(fused.begin(), fused.end(),
                                [](const Step& step) { return step.kind == Step::Kind::upconv; }),
                  1);
        EXPECT_TRUE(std::none_of(fused.begin(), fused.end(), [](const Step& step) {
            return step.kind == Step::Kind::concat || step.kind == Step::Kind::upsample2;
        }));
    }
    // The concat read by another node too: made, and the conv runs as written.
    Net shared("shared");
    Value y = shared.input("y", 4);
    Value joined = shared.concat({ shared.upsample2(shared.max_pool2(y)), y });
    shared.output("out", shared.conv(joined, "dec", 3, 3));
    shared.output("joined", joined);
    EXPECT_LT(onednn_vs_reference(shared, { random_tensor(8, 6, 4, 3) }), tolerance);
    const int conv = int(shared.nodes().size()) - 1;
    const std::vector<Step> steps = plan_steps(shared.nodes(), { conv, conv - 1 }, true);
    EXPECT_TRUE(std::none_of(steps.begin(), steps.end(),
                             [](const Step& step) { return step.kind == Step::Kind::upconv; }));
}

TEST(NnOps, ApplyKernelMatchesReference)
{
    for (int kernel : { 1, 3, 5, 21 }) {
        Net net("kpcn_head");
        Value logits = net.input("logits", kernel * kernel), image = net.input("image", 3);
        net.output("y", net.apply_kernel(logits, image, kernel));
        EXPECT_LT(onednn_vs_reference(net, { random_tensor(9, 12, kernel * kernel, 4, -4, 4),
                                             random_tensor(9, 12, 3, 5, 0, 10) }),
                  tolerance)
            << "kernel " << kernel;
    }
}

TEST(NnOps, ApplyKernelIsAWeightedAverage)
{
    // One huge logit picks one tap: the output is that neighbour, clamped at the border.
    const int k = 3;
    Tensor logits(4, 4, k * k, 0.0f), image = random_tensor(4, 4, 2, 6);
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x)
            logits.at(y, x, 0 * k + 2) = 100.0f;  // tap (dy, dx) = (-1, +1)
    Net net("pick");
    Value l = net.input("logits", k * k), i = net.input("image", 2);
    net.output("y", net.apply_kernel(l, i, k));
    std::string error;
    ASSERT_TRUE(net.load(Weights(), error)) << error;
    std::vector<Tensor> out;
    ASSERT_TRUE(net.run({ logits, image }, out, error)) << error;
    for (int y = 0; y < 4; ++y)
        for (int x = 0; x < 4; ++x)
            EXPECT_NEAR(out[0].at(y, x, 1), image.at(std::max(y - 1, 0), std::min(x + 1, 3), 1),
                        1e-6);
}

TEST(NnOps, ResultDoesNotDependOnThreadCount)
{
    Net net("threads");
    Value x = net.input("x", 8);
    Value y = net.conv(x, "c1", 32, 3);
    y = net.add(y, net.conv(y, "c2", 32, 3), Activation::relu);
    Value logits = net.conv(net.upsample2(net.max_pool2(y)), "k", 25, 3, Activation::none);
    net.output("y", net.apply_kernel(logits, net.slice(x, 0, 3), 5));
    std::string error;
    ASSERT_TRUE(net.load(random_weights(net, 9), error)) << error;
    const Tensor input = random_tensor(32, 48, 8, 10);
    std::vector<Tensor> many, one;
    ASSERT_TRUE(net.run({ input }, many, error)) << error;
    {
        tbb::global_control single(tbb::global_control::max_allowed_parallelism, 1);
        ASSERT_TRUE(net.run({ input }, one, error)) << error;
    }
    EXPECT_EQ(many[0].data, one[0].data);
}

}  // namespace

namespace {

// Residual adds are fused into the preceding conv (oneDNN sum post-op), accumulating into
// the residual's own buffer only when nothing else reads it; every case against the
// reference, which never fuses.
TEST(NnOps, FusedResidualAddsMatchReference)
{
    Net net("residuals");
    Value input = net.input("x", 16);
    Value a = net.add(input, net.conv(input, "c0", 16, 3, Activation::none));  // residual = input
    Value x = net.conv(a, "c1", 16, 3);
    Value r = net.conv(net.conv(x, "c2", 16, 3), "c3", 16, 3, Activation::none);
    Value block = net.add(x, r, Activation::relu);  // x stolen in place
    Value self = net.add(block, net.conv(block, "c4", 16, 3), Activation::relu);  // conv reads it
    Value kept = net.conv(self, "c5", 16, 3);
    Value later = net.add(kept, net.conv(kept, "c6", 16, 1));
    net.output("later", later);
    net.output("kept", kept);  // read after the add: must not be overwritten
    net.output("sum_of_convs", net.add(net.conv(later, "c7", 16, 3), net.conv(later, "c8", 16, 3)));
    EXPECT_LT(onednn_vs_reference(net, { random_tensor(12, 20, 16, 11) }), tolerance);
}

}  // namespace

namespace {

// A 1×1 kernel head read only through slices of its logits (KPCN's) is never run as a conv:
// each apply_kernel computes its slice's logits from the head's input (net.cpp Schedule
// fused_head). Against the reference, which runs the conv; a second head that is also an
// output must still be computed.
TEST(NnOps, FusedKernelHeadMatchesReference)
{
    Net net("head");
    Value x = net.input("x", 6);
    Value features = net.conv(x, "features", 16, 3);
    Value logits = net.conv(features, "head", 2 * 9, 1, Activation::none);
    Value image = net.slice(x, 0, 3);
    for (int step = 0; step < 2; ++step)
        image = net.apply_kernel(net.slice(logits, step * 9, 9), image, 3);
    net.output("y", image);
    Value shown = net.conv(features, "shown", 9, 1, Activation::none);
    net.output("z", net.apply_kernel(net.slice(shown, 0, 9), image, 3));
    net.output("shown", shown);
    EXPECT_LT(onednn_vs_reference(net, { random_tensor(20, 37, 6, 12) }), tolerance);
}

}  // namespace
