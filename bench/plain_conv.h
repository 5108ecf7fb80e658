// The yardstick of the network benchmarks (issues 5 and 6): one convolution + ReLU as
// oneDNN's own examples run it (nhwc activations, weights "any", primitive and buffers made
// once), timed in the same run as what is compared with it, in wall and process CPU time
// (the machine is shared: CPU time is the steadier of the two).
#pragma once

#include <sys/resource.h>

#include <algorithm>
#include <chrono>

#include <oneapi/dnnl/dnnl.hpp>

namespace mcdn_bench {

/// Wall and process CPU (user + system, all threads) seconds of one run of something.
struct Timing {
    double wall = 0, cpu = 0;
};

inline double process_cpu_seconds()
{
    rusage usage {};
    getrusage(RUSAGE_SELF, &usage);
    auto seconds = [](const timeval& t) { return double(t.tv_sec) + 1e-6 * t.tv_usec; };
    return seconds(usage.ru_utime) + seconds(usage.ru_stime);
}

/// Times f() once.
template <class F> Timing timed(F f)
{
    const auto wall0 = std::chrono::steady_clock::now();
    const double cpu0 = process_cpu_seconds();
    f();
    return { std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count(),
             process_cpu_seconds() - cpu0 };
}

/// The fastest of `repeats` runs of f() after one warm-up run (JIT, page faults), by wall
/// time and, separately, by CPU time.
template <class F> Timing fastest_of(int repeats, F f)
{
    f();
    Timing best { 1e30, 1e30 };
    for (int r = 0; r < repeats; ++r) {
        const Timing t = timed(f);
        best.wall = std::min(best.wall, t.wall);
        best.cpu = std::min(best.cpu, t.cpu);
    }
    return best;
}

/// One k×k in_c→out_c convolution + ReLU on height × width; its FLOPs in `flops`.
inline Timing plain_onednn_conv(int height, int width, int in_c, int out_c, int k, int repeats,
                                double* flops = nullptr)
{
    using tag = dnnl::memory::format_tag;
    using dt = dnnl::memory::data_type;
    dnnl::engine engine(dnnl::engine::kind::cpu, 0);
    dnnl::stream stream(engine);
    // The output the input's size: an even kernel (UpConvLayer's 2×2 phases) pads one less
    // after than before.
    const dnnl::memory::dim pad = k / 2, pad_after = (k - 1) / 2;
    dnnl::memory::desc src_md({ 1, in_c, height, width }, dt::f32, tag::nhwc);
    dnnl::memory::desc dst_md({ 1, out_c, height, width }, dt::f32, tag::nhwc);
    dnnl::memory::desc w_md({ out_c, in_c, k, k }, dt::f32, tag::any);
    dnnl::memory::desc b_md({ out_c }, dt::f32, tag::x);
    dnnl::convolution_forward::desc desc(dnnl::prop_kind::forward_inference,
                                         dnnl::algorithm::convolution_direct, src_md, w_md, b_md,
                                         dst_md, { 1, 1 }, { pad, pad }, { pad_after, pad_after });
    dnnl::post_ops post_ops;
    post_ops.append_eltwise(1.0f, dnnl::algorithm::eltwise_relu, 0.0f, 0.0f);
    dnnl::primitive_attr attr;
    attr.set_post_ops(post_ops);
    dnnl::convolution_forward::primitive_desc pd(desc, attr, engine);
    dnnl::memory src(src_md, engine), dst(dst_md, engine), weights(pd.weights_desc(), engine),
        bias(b_md, engine);
    // Every operand set: memory left as allocated may hold denormals or NaN, which the
    // vector units process many times slower.
    std::fill_n(static_cast<float*>(src.get_data_handle()), size_t(height) * width * in_c, 0.1f);
    std::fill_n(static_cast<float*>(weights.get_data_handle()),
                pd.weights_desc().get_size() / sizeof(float), 0.01f);
    std::fill_n(static_cast<float*>(bias.get_data_handle()), size_t(out_c), 0.0f);
    dnnl::convolution_forward conv(pd);
    if (flops)
        *flops = 2.0 * height * width * in_c * out_c * k * k;
    return fastest_of(repeats, [&] {
        conv.execute(stream, { { DNNL_ARG_SRC, src },
                               { DNNL_ARG_WEIGHTS, weights },
                               { DNNL_ARG_BIAS, bias },
                               { DNNL_ARG_DST, dst } });
        stream.wait();
    });
}

}  // namespace mcdn_bench
