// oneDNN 2.6 convolutions (onednn_conv.h). Direct algorithm, forward inference, NHWC
// activations, weights in whatever blocked layout the chosen kernel wants.
#include "nn/onednn_conv.h"
#include "nn/ops.h"

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
    : in_channels_(in_channels), out_channels_(out_channels), kernel_(kernel),
      activation_(activation), weights_oihw_(weights_oihw), bias_(bias)
{ }

ConvLayer::Prepared& ConvLayer::prepare(dnnl::engine& engine, dnnl::stream& stream, int height,
                                        int width, Tail tail)
{
    auto found = by_size_.find({ height, width, tail });
    if (found != by_size_.end())
        return found->second;

    ensure_jit_headroom();
    const memory::dim pad = kernel_ / 2;
    const memory::desc src_md({ 1, in_channels_, height, width }, dt::f32, tag::nhwc);
    const memory::desc dst_md({ 1, out_channels_, height, width }, dt::f32, tag::nhwc);
    const memory::desc weights_md({ out_channels_, in_channels_, kernel_, kernel_ }, dt::f32,
                                  tag::any);
    const memory::desc bias_md({ out_channels_ }, dt::f32, tag::x);
    const dnnl::convolution_forward::desc desc(
        dnnl::prop_kind::forward_inference, dnnl::algorithm::convolution_direct, src_md, weights_md,
        bias_md, dst_md, { 1, 1 }, { pad, pad }, { pad, pad });
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
    reshape(out, x.height, x.width, out_channels_);
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
    const memory::desc dst_md({ 1, out_channels_, x.height, x.width }, dt::f32, tag::nhwc);
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

}  // namespace nn
}  // namespace mcdn
