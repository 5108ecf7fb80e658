// oneDNN 2.6 convolutions (onednn_conv.h). Direct algorithm, forward inference, NHWC
// activations, weights in whatever blocked layout the chosen kernel wants.
#include "nn/onednn_conv.h"
#include "nn/ops.h"

#include <algorithm>
#include <new>
#include <sys/mman.h>
#include <sys/resource.h>

namespace mcdn {
namespace nn {

namespace {

// oneDNN 2.6 writes its JIT kernels into buffers it grows as it goes and does not check that
// they grew: under an address-space limit (`ulimit -v`, a farm slot's) with less than that
// left, creating a primitive crashes instead of failing. So where such a limit is set, a
// primitive is made only while this much more could still be mapped; otherwise
// std::bad_alloc, which the op reports as out of memory.
constexpr size_t kJitHeadroomBytes = size_t(64) << 20;

void ensure_jit_headroom()
{
    static const bool limited = [] {
        rlimit limit {};
        return getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY;
    }();
    if (!limited)
        return;
    void* probe = mmap(nullptr, kJitHeadroomBytes, PROT_NONE,
                       MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (probe == MAP_FAILED)
        throw std::bad_alloc();
    munmap(probe, kJitHeadroomBytes);
}

}  // namespace

using dnnl::memory;
using tag = memory::format_tag;
using dt = memory::data_type;

ConvLayer::ConvLayer(int in_channels, int out_channels, int kernel, Activation activation,
                     const std::vector<float>& weights_oihw, const std::vector<float>& bias)
    : ConvLayer(in_channels, out_channels, kernel,
                { kernel / 2, kernel / 2, kernel / 2, kernel / 2 }, activation, weights_oihw, bias)
{ }

ConvLayer::ConvLayer(int in_channels, int out_channels, int kernel, Padding padding,
                     Activation activation, const std::vector<float>& weights_oihw,
                     const std::vector<float>& bias)
    : in_channels_(in_channels), out_channels_(out_channels), kernel_(kernel), padding_(padding),
      activation_(activation), weights_oihw_(weights_oihw), bias_(bias)
{ }

ConvLayer::Prepared& ConvLayer::prepare(dnnl::engine& engine, dnnl::stream& stream, int height,
                                        int width, Tail tail)
{
    auto found = by_size_.find({ height, width, tail });
    if (found != by_size_.end())
        return found->second;

    ensure_jit_headroom();
    const memory::desc src_md({ 1, in_channels_, height, width }, dt::f32, tag::nhwc);
    const memory::desc dst_md({ 1, out_channels_, output_height(height), output_width(width) },
                              dt::f32, tag::nhwc);
    const memory::desc weights_md({ out_channels_, in_channels_, kernel_, kernel_ }, dt::f32,
                                  tag::any);
    const memory::desc bias_md({ out_channels_ }, dt::f32, tag::x);
    const dnnl::convolution_forward::desc desc(
        dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct, src_md, weights_md,
        bias_md, dst_md, { 1, 1 }, { padding_.top, padding_.left },
        { padding_.bottom, padding_.right });
    // Fused post-ops: the output is written once, already activated (and summed).
    dnnl::post_ops post_ops;
    if (activation_ == Activation::relu)
        post_ops.append_eltwise(1.0f, dnnl::algorithm::eltwise_relu, 0.0f, 0.0f);
    if (tail != Tail::none)
        post_ops.append_sum(1.0f);
    if (tail == Tail::sum_relu)
        post_ops.append_eltwise(1.0f, dnnl::algorithm::eltwise_relu, 0.0f, 0.0f);
    dnnl::primitive_attr attr;
    attr.set_post_ops(post_ops);
    const dnnl::convolution_forward::primitive_desc pd(desc, attr, engine);

    // The weights: reordered from OIHW once per layout (every size normally shares one).
    memory weights;
    for (auto& [layout, reordered] : weights_by_layout_)
        if (layout == pd.weights_desc())
            weights = reordered;
    if (!weights) {
        memory user({ { out_channels_, in_channels_, kernel_, kernel_ }, dt::f32, tag::oihw },
                    engine, weights_oihw_.data());
        weights = memory(pd.weights_desc(), engine);
        dnnl::reorder(user, weights).execute(stream, user, weights);
        stream.wait();
        weights_by_layout_.emplace_back(pd.weights_desc(), weights);
    }
    last_implementation_ = pd.impl_info_str();
    return by_size_
        .emplace(std::make_tuple(height, width, tail),
                 Prepared { dnnl::convolution_forward(pd), weights })
        .first->second;
}

void ConvLayer::run(dnnl::engine& engine, dnnl::stream& stream, const Tensor& x, Tensor& out)
{
    Prepared& prepared = prepare(engine, stream, x.height, x.width, Tail::none);
    reshape(out, output_height(x.height), output_width(x.width), out_channels_);
    execute(engine, stream, prepared, x, out);
}

void ConvLayer::run_accumulate(dnnl::engine& engine, dnnl::stream& stream, const Tensor& x,
                               Tensor& residual, Activation after_sum)
{
    execute(engine, stream,
            prepare(engine, stream, x.height, x.width,
                    after_sum == Activation::relu ? Tail::sum_relu : Tail::sum),
            x, residual);
}

void ConvLayer::execute(dnnl::engine& engine, dnnl::stream& stream, Prepared& prepared,
                        const Tensor& x, Tensor& out)
{
    const memory::desc src_md({ 1, in_channels_, x.height, x.width }, dt::f32, tag::nhwc);
    const memory::desc dst_md({ 1, out_channels_, out.height, out.width }, dt::f32, tag::nhwc);
    const memory::desc bias_md({ out_channels_ }, dt::f32, tag::x);
    // oneDNN only reads src and bias; its handles take non-const pointers.
    memory src(src_md, engine, const_cast<float*>(x.data.data()));
    memory dst(dst_md, engine, out.data.data());
    memory bias(bias_md, engine, bias_.data());
    prepared.primitive.execute(stream, { { DNNL_ARG_SRC, src },
                                         { DNNL_ARG_WEIGHTS, prepared.weights },
                                         { DNNL_ARG_BIAS, bias },
                                         { DNNL_ARG_DST, dst } });
    stream.wait();
}

namespace {

/// The 2×2 taps of x for one output phase of a 3×3 conv of upsample2(x), along one axis:
/// phase 0 (output row 2i) reads x's rows i - 1 and i, which carry the 3×3 kernel's rows
/// {0} and {1, 2}; phase 1 (row 2i + 1) reads rows i and i + 1, carrying {0, 1} and {2}.
constexpr int kTaps[2][2][2] = { { { 0, -1 }, { 1, 2 } }, { { 0, 1 }, { 2, -1 } } };

/// OIHW weights of phase (py, px)'s 2×2 conv, from the upsampled input's channels (the
/// first `up` of `in`) of the 3×3 weights.
std::vector<float> phase_weights(int py, int px, int up, int in, int out,
                                 const std::vector<float>& w)
{
    std::vector<float> phase(size_t(out) * up * 4, 0.0f);
    for (int o = 0; o < out; ++o)
        for (int c = 0; c < up; ++c)
            for (int a = 0; a < 2; ++a)
                for (int b = 0; b < 2; ++b) {
                    float sum = 0;
                    for (int row : kTaps[py][a])
                        for (int col : kTaps[px][b])
                            if (row >= 0 && col >= 0)
                                sum += w[((size_t(o) * in + c) * 3 + row) * 3 + col];
                    phase[((size_t(o) * up + c) * 2 + a) * 2 + b] = sum;
                }
    return phase;
}

/// OIHW weights of the skip's channels (the last `skip` of `in`) alone.
std::vector<float> skip_weights(int skip, int in, int out, const std::vector<float>& w)
{
    std::vector<float> part(size_t(out) * skip * 9);
    for (int o = 0; o < out; ++o)
        std::copy_n(w.begin() + (size_t(o) * in + in - skip) * 9, size_t(skip) * 9,
                    part.begin() + size_t(o) * skip * 9);
    return part;
}

}  // namespace

UpConvLayer::UpConvLayer(int up_channels, int skip_channels, int out_channels,
                         Activation activation, const std::vector<float>& weights_oihw,
                         const std::vector<float>& bias)
    : activation_(activation),
      skip_(skip_channels, out_channels, 3, Activation::none,
            skip_weights(skip_channels, up_channels + skip_channels, out_channels, weights_oihw),
            std::vector<float>(size_t(out_channels), 0.0f))
{
    // Phase 0 reads x's pixels i - 1 and i (padded before), phase 1 pixels i and i + 1
    // (padded after): each phase's output has x's size.
    for (int py = 0; py < 2; ++py)
        for (int px = 0; px < 2; ++px)
            phases_.emplace_back(up_channels, out_channels, 2,
                                 ConvLayer::Padding { 1 - py, py, 1 - px, px }, Activation::none,
                                 phase_weights(py, px, up_channels, up_channels + skip_channels,
                                               out_channels, weights_oihw),
                                 bias);
}

void UpConvLayer::run(dnnl::engine& engine, dnnl::stream& stream, const Tensor& x,
                      const Tensor& skip, Tensor& phase, Tensor& out)
{
    for (int p = 0; p < 4; ++p) {
        phases_[size_t(p)].run(engine, stream, x, phase);
        ops::scatter_phase(phase, p / 2, p % 2, out);
    }
    skip_.run_accumulate(engine, stream, skip, out, activation_);
}

}  // namespace nn
}  // namespace mcdn
