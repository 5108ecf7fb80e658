// The parameter-free ops run() uses: each a loop over output rows (nn/parallel.h). NHWC keeps
// a pixel's channels contiguous, so inner loops are memcpy or short vectorisable runs.
// Every output value is computed by one thread from its inputs alone: no cross-thread
// reductions, so the result does not depend on the number of threads.
#include <algorithm>
#include <cmath>
#include <cstring>

#include "core/huge_pages.h"
#include "nn/ops.h"
#include "nn/parallel.h"

namespace mcdn {
namespace nn {
void reshape(Tensor& t, int height, int width, int channels)
{
    t.height = height;
    t.width = width;
    t.channels = channels;
    if (t.size() <= t.data.size())
        return;  // never shrunk: a larger value may come back to this storage
    if (t.size() > t.data.capacity()) {
        t.data = std::vector<float>();  // grown without copying values nobody reads
        t.data.reserve(t.size());
        advise_huge_pages(t.data.data(), t.size() * sizeof(float));
    }
    t.data.resize(t.size());
}

namespace ops {

void add(const Tensor& a, const Tensor& b, Activation activation, Tensor& out)
{
    reshape(out, a.height, a.width, a.channels);
    const size_t row_size = size_t(a.width) * a.channels;
    const bool relu = activation == Activation::relu;
    parallel_rows(a.height, [&](int y) {
        const float* pa = a.pixel(y, 0);
        const float* pb = b.pixel(y, 0);
        float* po = out.pixel(y, 0);
        for (size_t i = 0; i < row_size; ++i)
            po[i] = relu ? std::max(pa[i] + pb[i], 0.0f) : pa[i] + pb[i];
    });
}

void max_pool2(const Tensor& x, Tensor& out)
{
    reshape(out, x.height / 2, x.width / 2, x.channels);
    const int channels = x.channels;
    parallel_rows(out.height, [&](int y) {
        for (int px = 0; px < out.width; ++px) {
            const float* p00 = x.pixel(2 * y, 2 * px);
            const float* p01 = p00 + channels;
            const float* p10 = x.pixel(2 * y + 1, 2 * px);
            const float* p11 = p10 + channels;
            float* po = out.pixel(y, px);
            for (int c = 0; c < channels; ++c)
                po[c] = std::max(std::max(p00[c], p01[c]), std::max(p10[c], p11[c]));
        }
    });
}

void upsample2(const Tensor& x, Tensor& out)
{
    reshape(out, x.height * 2, x.width * 2, x.channels);
    const size_t pixel_bytes = size_t(x.channels) * sizeof(float);
    parallel_rows(out.height, [&](int y) {
        for (int px = 0; px < out.width; ++px)
            std::memcpy(out.pixel(y, px), x.pixel(y / 2, px / 2), pixel_bytes);
    });
}

void concat(const std::vector<const Tensor*>& parts, Tensor& out)
{
    concat(parts, std::vector<char>(parts.size(), 0), out);
}

void concat(const std::vector<const Tensor*>& parts, const std::vector<char>& upsampled,
            Tensor& out)
{
    int channels = 0;
    for (const Tensor* part : parts)
        channels += part->channels;
    const int scale = upsampled[0] ? 2 : 1;
    reshape(out, parts[0]->height * scale, parts[0]->width * scale, channels);
    parallel_rows(out.height, [&](int y) {
        for (int px = 0; px < out.width; ++px) {
            float* po = out.pixel(y, px);
            for (size_t k = 0; k < parts.size(); ++k) {
                const Tensor& part = *parts[k];
                const float* from = upsampled[k] ? part.pixel(y / 2, px / 2) : part.pixel(y, px);
                std::memcpy(po, from, part.channels * sizeof(float));
                po += part.channels;
            }
        }
    });
}

void slice(const Tensor& x, int first, int count, Tensor& out)
{
    reshape(out, x.height, x.width, count);
    parallel_rows(x.height, [&](int y) {
        for (int px = 0; px < x.width; ++px)
            std::memcpy(out.pixel(y, px), x.pixel(y, px) + first, count * sizeof(float));
    });
}

void scatter_phase(const Tensor& phase, int py, int px, Tensor& out)
{
    // reshape() keeps the storage (and the phases already scattered) at the same shape.
    reshape(out, 2 * phase.height, 2 * phase.width, phase.channels);
    const size_t pixel_bytes = size_t(phase.channels) * sizeof(float);
    parallel_rows(phase.height, [&](int i) {
        for (int j = 0; j < phase.width; ++j)
            std::memcpy(out.pixel(2 * i + py, 2 * j + px), phase.pixel(i, j), pixel_bytes);
    });
}

}  // namespace ops
}  // namespace nn
}  // namespace mcdn
