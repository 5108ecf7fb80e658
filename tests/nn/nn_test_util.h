// What the nn tests share: random tensors and weights, and the error measure.
#pragma once

#include <algorithm>
#include <cmath>
#include <random>

#include "nn/nn.h"
#include "mcdn_test.h"

namespace nn_test {

using namespace mcdn::nn;

inline Tensor random_tensor(int height, int width, int channels, unsigned seed, float lo = -1,
                            float hi = 1)
{
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> u(lo, hi);
    Tensor t(height, width, channels);
    for (float& v : t.data)
        v = u(rng);
    return t;
}

/// Every parameter `net` expects, uniform in ±sqrt(3 / fan_in) (unit-variance outputs, so
/// activations neither vanish nor explode through the layers), biases in ±0.2.
inline Weights random_weights(const Net& net, unsigned seed)
{
    std::mt19937 rng(seed);
    Weights weights;
    weights.path = "random.mcdnw";
    for (const Net::Node& node : net.nodes())
        if (node.op == Net::Op::conv) {
            const int in_channels = net.nodes()[node.inputs[0]].channels;
            const float bound = std::sqrt(3.0f / (in_channels * node.kernel * node.kernel));
            std::uniform_real_distribution<float> w(-bound, bound), b(-0.2f, 0.2f);
            NamedTensor weight { node.name + ".weight",
                                 { node.channels, in_channels, node.kernel, node.kernel },
                                 {} };
            weight.values.resize(size_t(node.channels) * in_channels * node.kernel * node.kernel);
            for (float& v : weight.values)
                v = w(rng);
            NamedTensor bias { node.name + ".bias",
                               { node.channels },
                               std::vector<float>(node.channels) };
            for (float& v : bias.values)
                v = b(rng);
            weights.tensors.push_back(weight);
            weights.tensors.push_back(bias);
        }
    return weights;
}

/// max |a − ref| / (|ref| + rms(ref)): relative error, where values near zero (after a
/// ReLU, or a dot product that cancels) are judged against the tensor's typical magnitude,
/// not against themselves: float32 sums carry an absolute error of the terms' scale.
inline double relative_error(const Tensor& a, const Tensor& ref)
{
    EXPECT_EQ(a.height, ref.height);
    EXPECT_EQ(a.width, ref.width);
    EXPECT_EQ(a.channels, ref.channels);
    if (a.data.size() != ref.data.size() || ref.data.empty())
        return INFINITY;
    double sum_squares = 0, worst = 0;  // double: a sum of many squares
    for (float v : ref.data)
        sum_squares += double(v) * v;
    const double rms = std::sqrt(sum_squares / ref.data.size());
    for (size_t i = 0; i < a.data.size(); ++i)
        worst = std::max(worst, std::abs(double(a.data[i]) - ref.data[i])
                                    / (std::abs(double(ref.data[i])) + rms + 1e-30));
    return worst;
}

/// Builds and loads `net` with random weights, runs both backends; returns the error of
/// oneDNN's outputs against the reference.
inline double onednn_vs_reference(Net& net, const std::vector<Tensor>& inputs, unsigned seed = 1)
{
    std::string error;
    EXPECT_TRUE(net.load(random_weights(net, seed), error)) << error;
    std::vector<Tensor> fast, reference;
    EXPECT_TRUE(net.run(inputs, fast, error, Backend::onednn)) << error;
    EXPECT_TRUE(net.run(inputs, reference, error, Backend::reference)) << error;
    double worst = 0;
    for (size_t o = 0; o < std::min(fast.size(), reference.size()); ++o)
        worst = std::max(worst, relative_error(fast[o], reference[o]));
    return worst;
}

}  // namespace nn_test
