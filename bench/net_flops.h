// The FLOP count of a network of our engine (lib/src/nn), for the benchmarks' rates and
// compute floors.
#pragma once

#include "nn/nn.h"

namespace mcdn_bench {

/// Multiply-adds x 2 of a network per output pixel, from its ops (convs at their scale).
inline double flops_per_pixel(const mcdn::nn::Net& net)
{
    using mcdn::nn::Net;
    double flops = 0;
    for (const auto& node : net.nodes()) {
        const double area = double(node.scale) * node.scale;
        if (node.op == Net::Op::conv) {
            const int in = net.nodes()[node.inputs[0]].channels;
            flops += 2.0 * in * node.channels * node.kernel * node.kernel / area;
        } else if (node.op == Net::Op::apply_kernel) {
            flops += 2.0 * node.kernel * node.kernel * node.channels / area;
        }
    }
    return flops;
}

}  // namespace mcdn_bench
