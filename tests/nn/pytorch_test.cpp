// The engine against PyTorch: tests/data/nn/tiny_net*.mcdnw, made by
// training/common/make_nn_fixture.py (a random network using every op), must give
// PyTorch's outputs within 1e-4 relative.
#include "nn_test_util.h"

using namespace nn_test;

namespace {

/// The graph of TinyNet in make_nn_fixture.py, op for op.
Net tiny_net()
{
    Net net("tiny_net");
    Value x = net.input("features", 6);
    Value e1 = net.conv(net.conv(x, "enc1", 16, 5), "enc1b", 16, 3);
    Value e2 = net.conv(net.max_pool2(e1), "enc2", 24, 3);
    Value r = net.conv(net.conv(e2, "res.conv1", 24, 3), "res.conv2", 24, 3, Activation::none);
    e2 = net.add(e2, r, Activation::relu);
    Value b = net.conv(net.max_pool2(e2), "bottleneck", 32, 3);
    Value d2 = net.conv(net.concat({ net.upsample2(b), e2 }), "dec2", 24, 3);
    Value d1 = net.conv(net.concat({ net.upsample2(d2), e1 }), "dec1", 16, 3);
    Value logits = net.conv(d1, "kernel", 25, 3, Activation::none);
    net.output("denoised", net.apply_kernel(logits, net.slice(x, 0, 3), 5));
    net.output("decoder", d1);
    return net;
}

Tensor to_tensor(const NamedTensor& t)
{
    Tensor out(t.shape[0], t.shape[1], t.shape[2]);
    out.data = t.values;
    return out;
}

TEST(NnPyTorch, TinyNetMatchesPyTorch)
{
    Weights weights, io;
    std::string error;
    ASSERT_TRUE(read_weights(mcdn_test::test_data("nn/tiny_net.mcdnw"), weights, error)) << error;
    ASSERT_TRUE(read_weights(mcdn_test::test_data("nn/tiny_net_io.mcdnw"), io, error)) << error;
    Net net = tiny_net();
    ASSERT_TRUE(net.load(weights, error)) << error;
    const Tensor input = to_tensor(*io.find("input.features"));
    const Tensor denoised = to_tensor(*io.find("output.denoised"));
    const Tensor decoder = to_tensor(*io.find("output.decoder"));

    for (Backend backend : { Backend::onednn, Backend::reference }) {
        std::vector<Tensor> out;
        ASSERT_TRUE(net.run({ input }, out, error, backend)) << error;
        const double denoised_error = relative_error(out[0], denoised);
        const double decoder_error = relative_error(out[1], decoder);
        std::printf("%s vs PyTorch: max relative error %.3g (denoised), %.3g (decoder)\n",
                    backend == Backend::onednn ? "oneDNN   " : "reference", denoised_error,
                    decoder_error);
        EXPECT_LT(denoised_error, 1e-4);
        EXPECT_LT(decoder_error, 1e-4);
    }
}

TEST(NnPyTorch, TiledRunMatchesPyTorch)
{
    Weights weights, io;
    std::string error;
    ASSERT_TRUE(read_weights(mcdn_test::test_data("nn/tiny_net.mcdnw"), weights, error)) << error;
    ASSERT_TRUE(read_weights(mcdn_test::test_data("nn/tiny_net_io.mcdnw"), io, error)) << error;
    Net net = tiny_net();
    ASSERT_TRUE(net.load(weights, error)) << error;
    std::vector<Tensor> out;
    TileOptions options;
    options.tile_size = 8;
    ASSERT_TRUE(run_tiled(net, { to_tensor(*io.find("input.features")) }, out, error, options))
        << error;
    EXPECT_LT(relative_error(out[0], to_tensor(*io.find("output.denoised"))), 1e-4);
}

}  // namespace
