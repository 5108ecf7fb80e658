// The parameter-free ops of a network, twice: `ops::` is what run() uses (threaded over
// rows with TBB, no reductions across threads, so results do not depend on the thread
// count), `reference::` is plain loops written to be obviously right, used by the tests and
// by Backend::reference. Each op allocates `out`; inputs are NHWC tensors (mcdn/nn.h).
#pragma once

#include <vector>

#include "mcdn/nn.h"

namespace mcdn {
namespace nn {

namespace ops {
void add(const Tensor& a, const Tensor& b, Activation activation, Tensor& out);
void max_pool2(const Tensor& x, Tensor& out);
void upsample2(const Tensor& x, Tensor& out);
void concat(const std::vector<const Tensor*>& parts, Tensor& out);
void slice(const Tensor& x, int first, int count, Tensor& out);
void apply_kernel(const Tensor& logits, const Tensor& image, int kernel, Tensor& out);
}  // namespace ops

namespace reference {
/// k×k convolution, stride 1, zero padding k/2; weights OIHW as in the weights file;
/// accumulates in double so it is a fair yardstick for oneDNN's float sums.
void conv(const Tensor& x, const std::vector<float>& weights_oihw,
          const std::vector<float>& bias, int kernel, Activation activation, Tensor& out);
void add(const Tensor& a, const Tensor& b, Activation activation, Tensor& out);
void max_pool2(const Tensor& x, Tensor& out);
void upsample2(const Tensor& x, Tensor& out);
void concat(const std::vector<const Tensor*>& parts, Tensor& out);
void slice(const Tensor& x, int first, int count, Tensor& out);
void apply_kernel(const Tensor& logits, const Tensor& image, int kernel, Tensor& out);
}  // namespace reference

}  // namespace nn
}  // namespace mcdn
