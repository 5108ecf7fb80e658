// Inference engine throughput (lib/src/nn): each convolution shape of our networks through
// Net::run, against one plain oneDNN convolution of the same shape measured in the same
// run (primitive and buffers made once, then executed back to back); then whole networks
// through run_tiled. Prints a table; not a timed test. Target (issue 6): engine ≥ 60% of
// plain oneDNN.
//
//   nn_bench [size=256] [repeats=5]
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>
#include <vector>

#include <oneapi/dnnl/dnnl.hpp>

#include "nn/nn.h"
#include "plain_conv.h"

using namespace mcdn::nn;
using mcdn_bench::fastest_of;
using mcdn_bench::plain_onednn_conv;

namespace {

std::vector<float> random_values(size_t n, unsigned seed)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(-0.1f, 0.1f);
    std::vector<float> v(n);
    for (float& x : v)
        x = u(rng);
    return v;
}

Weights random_weights(const Net& net)
{
    Weights weights;
    unsigned seed = 1;
    for (const Net::Node& node : net.nodes())
        if (node.op == Net::Op::conv) {
            const int in_c = net.nodes()[node.inputs[0]].channels;
            weights.tensors.push_back(
                { node.name + ".weight",
                  { node.channels, in_c, node.kernel, node.kernel },
                  random_values(size_t(node.channels) * in_c * node.kernel * node.kernel,
                                seed++) });
            weights.tensors.push_back(
                { node.name + ".bias", { node.channels }, random_values(node.channels, seed++) });
        }
    return weights;
}

/// Convolution FLOPs of `net` on a height × width input (2 per multiply-add).
double conv_flops(const Net& net, int height, int width)
{
    double flops = 0;
    for (const Net::Node& node : net.nodes())
        if (node.op == Net::Op::conv)
            flops += 2.0 * height / node.scale * width / node.scale
                     * net.nodes()[node.inputs[0]].channels * node.channels * node.kernel
                     * node.kernel;
    return flops;
}

/// The mixing network of progressive denoising §4.3 (5×5 to 48, two residual blocks, 3×3
/// to 3 outputs per colour channel).
Net mix_net(int features)
{
    Net net("mix");
    Value x = net.conv(net.input("features", features), "conv1", 48, 5);
    for (const char* block : { "res1", "res2" }) {
        Value r = net.conv(x, std::string(block) + ".conv1", 48, 3);
        r = net.conv(r, std::string(block) + ".conv2", 48, 3, Activation::none);
        x = net.add(x, r, Activation::relu);
    }
    net.output("alpha", net.conv(x, "out", 9, 3, Activation::none));
    return net;
}

/// A KPCN-style UNet (3 levels) with a 5×5 softmax kernel head on the noisy colour.
Net kpcn_unet(int features)
{
    Net net("kpcn");
    Value x = net.input("features", features);
    Value e1 = net.conv(net.conv(x, "enc1a", 32, 3), "enc1b", 32, 3);
    Value e2 = net.conv(net.conv(net.max_pool2(e1), "enc2a", 48, 3), "enc2b", 48, 3);
    Value e3 = net.conv(net.conv(net.max_pool2(e2), "enc3a", 64, 3), "enc3b", 64, 3);
    Value d2 = net.conv(net.concat({ net.upsample2(e3), e2 }), "dec2", 48, 3);
    Value d1 = net.conv(net.concat({ net.upsample2(d2), e1 }), "dec1", 32, 3);
    Value logits = net.conv(d1, "kernel", 25, 3, Activation::none);
    net.output("denoised", net.apply_kernel(logits, net.slice(x, 0, 3), 5));
    return net;
}

}  // namespace

int main(int argc, char** argv)
{
    const int size = argc > 1 ? std::atoi(argv[1]) : 256;
    const int repeats = argc > 2 ? std::atoi(argv[2]) : 5;
    std::printf("single convolutions (+ReLU) on %dx%d, fastest of %d\n", size, size, repeats);
    std::printf("%-22s %10s %10s %10s %8s\n", "shape in->out kxk", "plain ms", "engine ms",
                "GFLOP/s", "ratio");
    struct Shape {
        int in_c, out_c, k;
    };
    for (Shape s : { Shape { 14, 48, 5 }, Shape { 48, 48, 3 }, Shape { 48, 9, 3 },
                     Shape { 27, 32, 3 }, Shape { 32, 32, 3 }, Shape { 112, 48, 3 },
                     Shape { 32, 25, 3 }, Shape { 100, 100, 5 } }) {
        Net net("conv");
        net.output("y", net.conv(net.input("x", s.in_c), "conv", s.out_c, s.k));
        std::string error;
        if (!net.load(random_weights(net), error)) {
            std::fprintf(stderr, "%s\n", error.c_str());
            return 1;
        }
        std::vector<Tensor> inputs { Tensor(size, size, s.in_c, 0.5f) }, outputs;
        const double engine = fastest_of(repeats, [&] { net.run(inputs, outputs, error); }).wall;
        const double plain = plain_onednn_conv(size, size, s.in_c, s.out_c, s.k, repeats).wall;
        const double flops = conv_flops(net, size, size);
        char name[64];
        std::snprintf(name, sizeof name, "%d->%d %dx%d", s.in_c, s.out_c, s.k, s.k);
        std::printf("%-22s %10.2f %10.2f %10.1f %7.0f%%\n", name, plain * 1e3, engine * 1e3,
                    flops / engine * 1e-9, 100.0 * plain / engine);
    }

    std::printf("\nwhole networks, run_tiled 256 on %dx%d\n", size * 2, size * 2);
    for (int which = 0; which < 2; ++which) {
        Net net = which == 0 ? mix_net(14) : kpcn_unet(27);
        std::string error;
        if (!net.load(random_weights(net), error)) {
            std::fprintf(stderr, "%s\n", error.c_str());
            return 1;
        }
        std::vector<Tensor> inputs { Tensor(size * 2, size * 2, net.channels(Value { 0 }), 0.5f) },
            outputs;
        const double seconds = fastest_of(std::max(repeats / 2, 1), [&] {
                                   run_tiled(net, inputs, outputs, error);
                               }).wall;
        const double flops = conv_flops(net, size * 2, size * 2);
        std::printf(
            "%-6s halo %3d: %8.1f ms, %6.1f GFLOP/s (untiled FLOPs), %6.1f GFLOP per 1920x1080\n",
            net.name().c_str(), net.receptive_radius(), seconds * 1e3, flops / seconds * 1e-9,
            conv_flops(net, 1080, 1920) * 1e-9);
    }
    return 0;
}
