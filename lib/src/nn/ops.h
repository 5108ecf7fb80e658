// The parameter-free ops of a network, twice: `ops::` is what run() uses (threaded over
// rows with TBB, no reductions across threads, so results do not depend on the thread
// count), `reference::` is plain loops written to be obviously right, used by the tests and
// by Backend::reference. Each op sizes `out` with reshape() (so run() can hand in storage
// left by an earlier value: no allocation, no page faults per tile); inputs are NHWC
// tensors (nn/nn.h).
#pragma once

#include <vector>

#include "nn/nn.h"

namespace mcdn {
namespace nn {

/// Gives t the shape (height, width, channels), keeping its storage when it is big enough;
/// the values are unspecified (the op writes every one). t.data may then hold more than
/// t.size() floats (storage is never shrunk, so it is neither re-zeroed nor re-faulted when
/// a larger value reuses it): inside the engine use size(), not data.size().
void reshape(Tensor& t, int height, int width, int channels);

namespace ops {
void add(const Tensor& a, const Tensor& b, Activation activation, Tensor& out);
void max_pool2(const Tensor& x, Tensor& out);
void upsample2(const Tensor& x, Tensor& out);
void concat(const std::vector<const Tensor*>& parts, Tensor& out);
/// concat with the parts marked in `upsampled` read through upsample2 (given at half
/// resolution): each output pixel written once, no upsampled copy made first.
void concat(const std::vector<const Tensor*>& parts, const std::vector<char>& upsampled,
            Tensor& out);
void slice(const Tensor& x, int first, int count, Tensor& out);
/// One output phase of UpConvLayer into its pixels: out (reshaped to twice phase's height and
/// width, its other pixels kept) gets pixel (2i + py, 2j + px) from phase's pixel (i, j).
void scatter_phase(const Tensor& phase, int py, int px, Tensor& out);
void apply_kernel(const Tensor& logits, const Tensor& image, int kernel, Tensor& out);
/// The same with the k×k logits at channels [first_channel, first_channel + k²) of `logits`
/// (a slice that need not be copied out first).
void apply_kernel(const Tensor& logits, int first_channel, const Tensor& image, int kernel,
                  Tensor& out);
/// The same with the logits a 1×1 convolution of `features` (no activation), computed row
/// by row inside (the fused kernel head): head_weights [k²][features.channels] (OIHW rows),
/// head_bias [k²].
void apply_kernel_head(const Tensor& features, const float* head_weights, const float* head_bias,
                       const Tensor& image, int kernel, Tensor& out);
}  // namespace ops

namespace reference {
/// k×k convolution, stride 1, zero padding k/2; weights OIHW as in the weights file;
/// accumulates in double so it is a fair yardstick for oneDNN's float sums.
void conv(const Tensor& x, const std::vector<float>& weights_oihw, const std::vector<float>& bias,
          int kernel, Activation activation, Tensor& out);
void add(const Tensor& a, const Tensor& b, Activation activation, Tensor& out);
void max_pool2(const Tensor& x, Tensor& out);
void upsample2(const Tensor& x, Tensor& out);
void concat(const std::vector<const Tensor*>& parts, Tensor& out);
void slice(const Tensor& x, int first, int count, Tensor& out);
void apply_kernel(const Tensor& logits, const Tensor& image, int kernel, Tensor& out);
}  // namespace reference

}  // namespace nn
}  // namespace mcdn
