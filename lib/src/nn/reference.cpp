// Plain-loop reference of every op (ops.h): no threads, no pointer arithmetic, double
// accumulation. Slow; the tests compare the oneDNN path against it on random inputs.
#include <algorithm>
#include <cmath>

#include "nn/ops.h"

namespace mcdn {
namespace nn {
namespace reference {

static float activate(double v, Activation activation)
{
    return float(activation == Activation::relu ? std::max(v, 0.0) : v);
}

void conv(const Tensor& x, const std::vector<float>& weights_oihw, const std::vector<float>& bias,
          int kernel, Activation activation, Tensor& out)
{
    const int out_channels = int(bias.size()), in_channels = x.channels, pad = kernel / 2;
    out = Tensor(x.height, x.width, out_channels);
    for (int y = 0; y < x.height; ++y)
        for (int px = 0; px < x.width; ++px)
            for (int o = 0; o < out_channels; ++o) {
                double sum = bias[o];
                for (int ky = 0; ky < kernel; ++ky)
                    for (int kx = 0; kx < kernel; ++kx) {
                        const int sy = y + ky - pad, sx = px + kx - pad;
                        if (sy < 0 || sy >= x.height || sx < 0 || sx >= x.width)
                            continue;  // same padding with zeros
                        for (int i = 0; i < in_channels; ++i)
                            sum += double(weights_oihw[((size_t(o) * in_channels + i) * kernel + ky)
                                                           * kernel
                                                       + kx])
                                   * x.at(sy, sx, i);
                    }
                out.at(y, px, o) = activate(sum, activation);
            }
}

void add(const Tensor& a, const Tensor& b, Activation activation, Tensor& out)
{
    out = Tensor(a.height, a.width, a.channels);
    for (size_t i = 0; i < a.size(); ++i)
        out.data[i] = activate(double(a.data[i]) + b.data[i], activation);
}

void max_pool2(const Tensor& x, Tensor& out)
{
    out = Tensor(x.height / 2, x.width / 2, x.channels);
    for (int y = 0; y < out.height; ++y)
        for (int px = 0; px < out.width; ++px)
            for (int c = 0; c < x.channels; ++c)
                out.at(y, px, c) =
                    std::max({ x.at(2 * y, 2 * px, c), x.at(2 * y, 2 * px + 1, c),
                               x.at(2 * y + 1, 2 * px, c), x.at(2 * y + 1, 2 * px + 1, c) });
}

void upsample2(const Tensor& x, Tensor& out)
{
    out = Tensor(x.height * 2, x.width * 2, x.channels);
    for (int y = 0; y < out.height; ++y)
        for (int px = 0; px < out.width; ++px)
            for (int c = 0; c < x.channels; ++c)
                out.at(y, px, c) = x.at(y / 2, px / 2, c);
}

void concat(const std::vector<const Tensor*>& parts, Tensor& out)
{
    int channels = 0;
    for (const Tensor* part : parts)
        channels += part->channels;
    out = Tensor(parts[0]->height, parts[0]->width, channels);
    for (int y = 0; y < out.height; ++y)
        for (int px = 0; px < out.width; ++px) {
            int c_out = 0;
            for (const Tensor* part : parts)
                for (int c = 0; c < part->channels; ++c)
                    out.at(y, px, c_out++) = part->at(y, px, c);
        }
}

void slice(const Tensor& x, int first, int count, Tensor& out)
{
    out = Tensor(x.height, x.width, count);
    for (int y = 0; y < x.height; ++y)
        for (int px = 0; px < x.width; ++px)
            for (int c = 0; c < count; ++c)
                out.at(y, px, c) = x.at(y, px, first + c);
}

void apply_kernel(const Tensor& logits, const Tensor& image, int kernel, Tensor& out)
{
    const int pad = kernel / 2, taps = kernel * kernel;
    out = Tensor(image.height, image.width, image.channels);
    std::vector<double> weight(taps);
    for (int y = 0; y < image.height; ++y)
        for (int px = 0; px < image.width; ++px) {
            // KPCN eq. 9: softmax over the taps (shifted by the max so exp cannot overflow).
            double max_logit = logits.at(y, px, 0), sum = 0;
            for (int t = 1; t < taps; ++t)
                max_logit = std::max(max_logit, double(logits.at(y, px, t)));
            for (int t = 0; t < taps; ++t)
                sum += weight[t] = std::exp(logits.at(y, px, t) - max_logit);
            for (int c = 0; c < image.channels; ++c) {
                double value = 0;
                for (int dy = 0; dy < kernel; ++dy)
                    for (int dx = 0; dx < kernel; ++dx) {
                        const int sy = std::clamp(y + dy - pad, 0, image.height - 1);
                        const int sx = std::clamp(px + dx - pad, 0, image.width - 1);
                        value += weight[dy * kernel + dx] * image.at(sy, sx, c);
                    }
                out.at(y, px, c) = float(value / sum);
            }
        }
}

}  // namespace reference
}  // namespace nn
}  // namespace mcdn
