// The convolutions of a network on oneDNN, behind one small class: a ConvLayer owns its
// weights in the layout oneDNN chose (format_tag::any, reordered once per layout, which in
// practice is once) and a primitive per input size it has seen (a tiled run sees a handful).
// Activations stay NHWC, so consecutive layers need no reorders; ReLU is a fused post-op.
#pragma once

#include <map>
#include <tuple>
#include <utility>
#include <vector>

#include <oneapi/dnnl/dnnl.hpp>

#include "nn/net_plan.h"
#include "nn/nn.h"

namespace mcdn {
namespace nn {

class ConvLayer {
public:
    ConvLayer(int in_channels, int out_channels, int kernel, Activation activation,
              const std::vector<float>& weights_oihw, const std::vector<float>& bias);
    /// out = activation(conv(x) + bias); x must have in_channels channels. out keeps its
    /// storage when it is big enough (ops.h reshape).
    void run(dnnl::engine& engine, dnnl::stream& stream, const Tensor& x, Tensor& out);
    /// A residual connection fused into the convolution (oneDNN's sum post-op):
    /// residual = after_sum(residual + activation(conv(x) + bias)), in place, so the
    /// network's add() costs no separate pass over memory.
    void run_accumulate(dnnl::engine& engine, dnnl::stream& stream, const Tensor& x,
                        Tensor& residual, Activation after_sum);
    /// oneDNN's name for the implementation it picked for the last size run ("jit:avx512...").
    std::string implementation() const { return last_implementation_; }

private:
    struct Prepared {
        dnnl::convolution_forward primitive;
        dnnl::memory weights;
    };
    // What follows the convolution: nothing, a sum, a sum then ReLU.
    enum class Tail { none, sum, sum_relu };
    Prepared& prepare(dnnl::engine& engine, dnnl::stream& stream, int height, int width, Tail tail);
    void execute(dnnl::engine& engine, dnnl::stream& stream, Prepared& prepared, const Tensor& x,
                 Tensor& out);

    int in_channels_, out_channels_, kernel_;
    Activation activation_;
    std::vector<float> weights_oihw_, bias_;
    std::map<std::tuple<int, int, Tail>, Prepared> by_size_;
    std::vector<std::pair<dnnl::memory::desc, dnnl::memory>> weights_by_layout_;
    std::string last_implementation_;
};

/// What Net keeps between runs: the engine, a stream, one ConvLayer per conv node, and the
/// storage of freed values (reused by the next values and the next tiles).
struct NetState {
    dnnl::engine engine { dnnl::engine::kind::cpu, 0 };
    dnnl::stream stream { engine };
    std::map<int, ConvLayer> convs;  // by node id
    /// How the network runs (net_plan.h): [0] the oneDNN backend's, [1] the reference's;
    /// where its values live, and the storage of each slot while no value holds it.
    std::vector<Step> plan[2];
    StoragePlan storage[2];
    std::vector<std::vector<float>> slots[2];
    /// Storage another net handed over (Net::give_buffers), taken where a slot has none.
    std::vector<std::vector<float>> spare;
};

}  // namespace nn
}  // namespace mcdn
