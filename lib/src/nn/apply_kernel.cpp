// ops::apply_kernel (KPCN eq. 9), vectorised across the pixels of a row: the image is first
// copied to planes with a replicated border of k/2 pixels (so no tap needs a clamp), the
// row's logits are transposed to tap-major rows (so the softmax max, exp and sum, and every
// tap's multiply-add, run on 16 consecutive pixels at a time). The sums run over the taps in
// the reference's order, one pixel per lane: the result does not depend on the ISA's lane
// count beyond FMA rounding, nor on the thread count (every pixel is one thread's).
#include <algorithm>
#include <vector>

#include "core/simd.h"
#include "nn/ops.h"
#include "nn/parallel.h"

namespace mcdn {
namespace nn {
namespace ops {

namespace {

int round_up16(int n)
{
    return (n + kLanes - 1) / kLanes * kLanes;
}

/// The image as one plane per channel, `pad` replicated pixels around it, rows of
/// `stride` floats (room for a last vector that reads past the right border).
struct PaddedPlanes {
    int pad = 0, stride = 0, rows = 0, channels = 0;
    std::vector<float> values;
    const float* row(int c, int padded_y) const
    {
        return values.data() + (size_t(c) * rows + padded_y) * stride;
    }
};

void make_planes(const Tensor& image, int pad, PaddedPlanes& planes)
{
    planes.pad = pad;
    planes.stride = round_up16(image.width + 2 * pad) + kLanes;
    planes.rows = image.height + 2 * pad;
    planes.channels = image.channels;
    planes.values.resize(size_t(planes.channels) * planes.rows * planes.stride);
    parallel_row_blocks(planes.rows, [&](int first, int last) {
        for (int py = first; py != last; ++py) {
            const int y = std::clamp(py - pad, 0, image.height - 1);  // edge clamp
            for (int c = 0; c < planes.channels; ++c) {
                float* out = planes.values.data() + (size_t(c) * planes.rows + py) * planes.stride;
                for (int px = 0; px < image.width + 2 * pad; ++px)
                    out[px] = image.at(y, std::clamp(px - pad, 0, image.width - 1), c);
                std::fill(out + image.width + 2 * pad, out + planes.stride, 0.0f);
            }
        }
    });
}

/// Per-thread scratch of one row: the weights tap-major, the per-pixel max and total, the
/// per-channel sums.
struct RowScratch {
    std::vector<float> weights, max_logit, total, sums, features;
};

/// Where the logits come from: channels [first, first + k²) of a tensor, or (the fused
/// head) a 1×1 convolution of `features` computed here, row by row, so the k²-channel
/// logits of the whole tile never exist in memory (they would be KPCN's widest value: 125
/// channels of every window pixel, written once and read once).
struct Job {
    const Tensor* logits;  // or nullptr: the head below
    int first;             // logits channel of tap 0
    const Tensor* features = nullptr;
    const float* head_weights = nullptr;  // [tap][feature channel]
    const float* head_bias = nullptr;     // [tap]
    const PaddedPlanes* planes;
    int kernel;
    Tensor* out;
};

/// Lane j of the first row of a swap_blocks pair: a[j], or b[j − d] where bit d of j is
/// set (lanes of b count from 16); of the second row: a[j + d], or b[j] where it is set.
constexpr int low_lane(int j, int d)
{
    return j & d ? 16 + j - d : j;
}
constexpr int high_lane(int j, int d)
{
    return j & d ? 16 + j : j + d;
}

/// One round of a 16×16 transpose in registers: for each pair of rows (i, i + d) with bit
/// d of i clear, the off-diagonal blocks of size d trade places.
template <int d> MCDN_INLINE void swap_blocks(vfloat16 r[kLanes])
{
#define MCDN_LANES(f)                                                                              \
    f(0, d), f(1, d), f(2, d), f(3, d), f(4, d), f(5, d), f(6, d), f(7, d), f(8, d), f(9, d),      \
        f(10, d), f(11, d), f(12, d), f(13, d), f(14, d), f(15, d)
    for (int i = 0; i < kLanes; ++i)
        if (!(i & d)) {
            const vfloat16 a = r[i], b = r[i + d];
            r[i] = __builtin_shufflevector(a, b, MCDN_LANES(low_lane));
            r[i + d] = __builtin_shufflevector(a, b, MCDN_LANES(high_lane));
        }
#undef MCDN_LANES
}

/// Row y of `features` (channels a multiple of 16) channel-major into `out` (rows of
/// lanes_width, zero past `width`), 16 pixels × 16 channels at a time: four rounds of
/// swap_blocks (8, 4, 2, 1) instead of 256 scalar moves.
MCDN_INLINE void transpose_row(const Tensor& features, int y, int width, int lanes_width,
                               float* out)
{
    for (int x = 0; x < lanes_width; x += kLanes)
        for (int k0 = 0; k0 < features.channels; k0 += kLanes) {
            vfloat16 r[kLanes];
            for (int i = 0; i < kLanes; ++i)
                r[i] = x + i < width ? load16(features.pixel(y, x + i) + k0) : vfloat16 {};
            swap_blocks<8>(r);
            swap_blocks<4>(r);
            swap_blocks<2>(r);
            swap_blocks<1>(r);
            for (int i = 0; i < kLanes; ++i)
                store16(out + size_t(k0 + i) * lanes_width + x, r[i]);
        }
}

/// Tap-major logits of row y into s.weights; the lanes past the row's end get 0 (finite,
/// never written out).
MCDN_INLINE void row_logits(const Job& job, int y, int lanes_width, RowScratch& s)
{
    const int width = job.out->width, taps = job.kernel * job.kernel;
    if (job.logits) {
        for (int px = 0; px < lanes_width; ++px) {
            const float* z = px < width ? job.logits->pixel(y, px) + job.first : nullptr;
            for (int t = 0; t < taps; ++t)
                s.weights[size_t(t) * lanes_width + px] = z ? z[t] : 0.0f;
        }
        return;
    }
    // The head: z_t = bias_t + sum_k w_tk f_k, 16 pixels per vector, over the features
    // made channel-major first.
    const Tensor& features = *job.features;
    const int inputs = features.channels;
    s.features.resize(size_t(inputs) * lanes_width);
    if (inputs % kLanes == 0)
        transpose_row(features, y, width, lanes_width, s.features.data());
    else
        for (int px = 0; px < lanes_width; ++px) {
            const float* f = px < width ? features.pixel(y, px) : nullptr;
            for (int k = 0; k < inputs; ++k)
                s.features[size_t(k) * lanes_width + px] = f ? f[k] : 0.0f;
        }
    // Five taps at a time: five independent sums keep the FMA units busy (one sum alone
    // waits on each FMA's latency); each sum still runs over k in order.
    constexpr int kGroup = 5;
    for (int x = 0; x < lanes_width; x += kLanes)
        for (int t0 = 0; t0 < taps; t0 += kGroup) {
            const int group = std::min(kGroup, taps - t0);
            vfloat16 z[kGroup];
            for (int g = 0; g < kGroup; ++g)
                z[g] = splat16(g < group ? job.head_bias[t0 + g] : 0.0f);
            for (int k = 0; k < inputs; ++k) {
                const vfloat16 f = load16(&s.features[size_t(k) * lanes_width + x]);
                for (int g = 0; g < kGroup; ++g)
                    if (g < group)
                        z[g] += splat16(job.head_weights[size_t(t0 + g) * inputs + k]) * f;
            }
            for (int g = 0; g < group; ++g)
                store16(&s.weights[size_t(t0 + g) * lanes_width + x], z[g]);
        }
}

MCDN_INLINE void row_impl(const Job& job, int y, RowScratch& s)
{
    const int width = job.out->width, lanes_width = round_up16(width);
    const int kernel = job.kernel, taps = kernel * kernel, channels = job.planes->channels;
    s.weights.resize(size_t(taps) * lanes_width);
    s.max_logit.resize(lanes_width);
    s.total.resize(lanes_width);
    s.sums.resize(size_t(channels) * lanes_width);
    row_logits(job, y, lanes_width, s);
    for (int x = 0; x < lanes_width; x += kLanes) {
        // Softmax, shifted by the max so exp cannot overflow; exp_neg16 is good to ~2e-7.
        vfloat16 max = load16(&s.weights[x]);
        for (int t = 1; t < taps; ++t) {
            const vfloat16 z = load16(&s.weights[size_t(t) * lanes_width + x]);
            max = z > max ? z : max;
        }
        vfloat16 total = {};
        for (int t = 0; t < taps; ++t) {
            float* w = &s.weights[size_t(t) * lanes_width + x];
            const vfloat16 e = exp_neg16(max - load16(w));
            store16(w, e);
            total += e;
        }
        store16(&s.total[x], total);
        // The weighted sum of the neighbourhood, tap by tap in the reference's order.
        for (int c = 0; c < channels; ++c) {
            vfloat16 sum = {};
            for (int dy = 0; dy < kernel; ++dy) {
                const float* row = job.planes->row(c, y + dy) + x;
                for (int dx = 0; dx < kernel; ++dx)
                    sum += load16(&s.weights[size_t(dy * kernel + dx) * lanes_width + x])
                           * load16(row + dx);
            }
            store16(&s.sums[size_t(c) * lanes_width + x], sum);
        }
    }
    for (int px = 0; px < width; ++px) {
        float* out = job.out->pixel(y, px);
        const float inverse_total = 1.0f / s.total[px];
        for (int c = 0; c < channels; ++c)
            out[c] = s.sums[size_t(c) * lanes_width + px] * inverse_total;
    }
}

MCDN_TARGET_AVX512 void row_avx512(const Job& job, int y, RowScratch& s)
{
    row_impl(job, y, s);
}
MCDN_TARGET_AVX2 void row_avx2(const Job& job, int y, RowScratch& s)
{
    row_impl(job, y, s);
}
void row_baseline(const Job& job, int y, RowScratch& s)
{
    row_impl(job, y, s);
}

/// out from `image` and the logits `job` names: the image padded once, then the rows of
/// out, each computed by one thread.
void run_rows(Job job, const Tensor& image, Tensor& out)
{
    static thread_local PaddedPlanes planes;  // kept: no allocation per call
    make_planes(image, job.kernel / 2, planes);
    reshape(out, image.height, image.width, image.channels);
    job.planes = &planes;
    job.out = &out;
    const Isa isa = detect_isa();
    auto row = isa == Isa::Avx512 ? row_avx512 : isa == Isa::Avx2 ? row_avx2 : row_baseline;
    parallel_row_blocks(image.height, [&](int first, int last) {
        static thread_local RowScratch scratch;  // kept: no allocation per block
        for (int y = first; y != last; ++y)
            row(job, y, scratch);
    });
}

}  // namespace

void apply_kernel(const Tensor& logits, int first_channel, const Tensor& image, int kernel,
                  Tensor& out)
{
    run_rows({ &logits, first_channel, nullptr, nullptr, nullptr, nullptr, kernel, nullptr }, image,
             out);
}

void apply_kernel_head(const Tensor& features, const float* head_weights, const float* head_bias,
                       const Tensor& image, int kernel, Tensor& out)
{
    run_rows({ nullptr, 0, &features, head_weights, head_bias, nullptr, kernel, nullptr }, image,
             out);
}

void apply_kernel(const Tensor& logits, const Tensor& image, int kernel, Tensor& out)
{
    apply_kernel(logits, 0, image, kernel, out);
}

}  // namespace ops
}  // namespace nn
}  // namespace mcdn
