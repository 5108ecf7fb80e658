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
    /// Zero padding of the input: rows above and below, columns left and right.
    struct Padding {
        int top, bottom, left, right;
    };
    /// Padded by kernel / 2 on every side (the output the input's size, for an odd kernel),
    /// or by `padding`.
    ConvLayer(int in_channels, int out_channels, int kernel, Activation activation,
              const std::vector<float>& weights_oihw, const std::vector<float>& bias);
    ConvLayer(int in_channels, int out_channels, int kernel, Padding padding, Activation activation,
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
    int output_height(int height) const
    {
        return height + padding_.top + padding_.bottom - kernel_ + 1;
    }
    int output_width(int width) const
    {
        return width + padding_.left + padding_.right - kernel_ + 1;
    }
    Prepared& prepare(dnnl::engine& engine, dnnl::stream& stream, int height, int width, Tail tail);
    void execute(dnnl::engine& engine, dnnl::stream& stream, Prepared& prepared, const Tensor& x,
                 Tensor& out);

    int in_channels_, out_channels_, kernel_;
    Padding padding_;
    Activation activation_;
    std::vector<float> weights_oihw_, bias_;
    std::map<std::tuple<int, int, Tail>, Prepared> by_size_;
    std::vector<std::pair<dnnl::memory::desc, dnnl::memory>> weights_by_layout_;
    std::string last_implementation_;
};

/// A 3×3 convolution of concat(upsample2(x), skip) (a UNet decoder's first conv) with neither
/// made. Nearest upsampling repeats each pixel of x over 2×2, so each of the four output
/// phases (the pixels 2i + py, 2j + px) reads x through 2×2 taps whose weights are sums of
/// the 3×3 ones: a 2×2 convolution of x per phase, at x's resolution, 4 taps of x per output
/// pixel instead of 9 (in OIDN's UNet 46% of the multiply-adds are on upsampled values).
/// Each phase is scattered into its pixels of out (through scratch of x's size), then the
/// skip's own 3×3 convolution is added to them (oneDNN's sum post-op), then the activation.
/// Equal to the conv of the concat up to float rounding.
class UpConvLayer {
public:
    /// weights_oihw: out_channels × (up_channels + skip_channels) × 3 × 3, the upsampled
    /// input's channels first (the concat's order).
    UpConvLayer(int up_channels, int skip_channels, int out_channels, Activation activation,
                const std::vector<float>& weights_oihw, const std::vector<float>& bias);
    /// out = activation(conv3x3(concat(upsample2(x), skip)) + bias), skip at twice x's size;
    /// `phase` is scratch: x's pixels of out's channels.
    void run(dnnl::engine& engine, dnnl::stream& stream, const Tensor& x, const Tensor& skip,
             Tensor& phase, Tensor& out);

private:
    Activation activation_;
    std::vector<ConvLayer> phases_;  // p = 2 py + px
    ConvLayer skip_;
};

/// What Net keeps between runs: the engine, a stream, a layer per conv the fast plan runs,
/// and the storage of freed values (reused by the next values and the next tiles).
struct NetState {
    dnnl::engine engine { dnnl::engine::kind::cpu, 0 };
    dnnl::stream stream { engine };
    std::map<int, ConvLayer> convs;      // by node id: Step::Kind::conv and conv_sum
    std::map<int, UpConvLayer> upconvs;  // by node id: the convs planned as Step::Kind::upconv
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
