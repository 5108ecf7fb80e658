// The compute floor of a chain on one frame size, two ways: the FLOPs of its networks
// (KPCN's two branches; the best chain runs KPCN twice, for the denoised image and SURE's
// probe, plus the mixing network) at the rate a plain oneDNN 3x3 48->48 conv + ReLU reaches
// on a frame of that size; and each of the networks' convolutions run alone as a plain
// oneDNN conv on the whole frame at its own shape (channels, kernel, scale), summed: what
// the convs cost without tiling, halos or anything between them. Both timed in this run;
// bench/production divides whole-process times by them. For OIDN's UNet also the convs as
// the engine runs them (`layers_oidn_as_run_s`): a decoder conv of concat(upsample2(x), skip)
// as its four 2×2 phase convs at x's size and the skip's 3×3 conv (onednn_conv.h).
//
//   bench_floor WIDTH HEIGHT [OIDN.tza]   prints one JSON object; with OIDN's weights also
//                                         OIDN's UNet's floor (--oidn; --oidn --sure --mix)
#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <string>

#include "cnn/cnn_steps.h"
#include "mcdn/cnn.h"
#include "mcdn/mix.h"
#include "mix/mix_steps.h"
#include "nn/net_plan.h"
#include "oidn/oidn_steps.h"

#include "net_flops.h"
#include "plain_conv.h"

using namespace mcdn;
using mcdn_bench::flops_per_pixel;

namespace {

/// Every conv of `net` as a plain oneDNN conv on the frame (at the node's scale), summed.
double plain_layers_seconds(const nn::Net& net, int height, int width)
{
    double total = 0;
    for (const auto& node : net.nodes())
        if (node.op == nn::Net::Op::conv) {
            const int in = net.nodes()[node.inputs[0]].channels;
            const int h = std::max(1, height / node.scale), w = std::max(1, width / node.scale);
            total += mcdn_bench::plain_onednn_conv(h, w, in, node.channels, node.kernel, 2).wall;
        }
    return total;
}

/// The same for the convs the oneDNN backend runs (nn/net_plan.h): an upconv as its four
/// 2×2 phase convs on the upsampled input's channels at that input's size, and its skip's
/// 3×3 conv.
double plain_run_layers_seconds(const nn::Net& net, int height, int width)
{
    const auto& nodes = net.nodes();
    std::vector<char> upconv(nodes.size(), 0);
    for (const nn::Step& step : nn::plan_steps(nodes, net.output_ids(), true))
        upconv[size_t(step.id)] = step.kind == nn::Step::Kind::upconv;
    double total = 0;
    for (size_t id = 0; id < nodes.size(); ++id) {
        const auto& node = nodes[id];
        if (node.op != nn::Net::Op::conv)
            continue;
        const int h = std::max(1, height / node.scale), w = std::max(1, width / node.scale);
        const int in = nodes[size_t(node.inputs[0])].channels;
        if (!upconv[id]) {
            total += mcdn_bench::plain_onednn_conv(h, w, in, node.channels, node.kernel, 2).wall;
            continue;
        }
        const auto& joined = nodes[size_t(node.inputs[0])];
        const int up = nodes[size_t(joined.inputs[0])].channels;
        total += 4 * mcdn_bench::plain_onednn_conv(std::max(1, h / 2), std::max(1, w / 2), up,
                                                   node.channels, 2, 2)
                         .wall
                 + mcdn_bench::plain_onednn_conv(h, w, in - up, node.channels, 3, 2).wall;
    }
    return total;
}

}  // namespace

int main(int argc, char** argv)
{
    if (argc != 3 && argc != 4) {
        std::fprintf(stderr, "usage: bench_floor WIDTH HEIGHT [OIDN.tza]\n");
        return 2;
    }
    const int w = std::atoi(argv[1]), h = std::atoi(argv[2]);
    std::string error;
    kpcn::Model kpcn;
    nn::Net mix;
    if (!kpcn::load_model(kpcn, default_cnn_weights(), error)
        || !load_mix_net(mix, default_mix_weights("cnn"), error)) {
        std::fprintf(stderr, "bench_floor: %s\n", error.c_str());
        return 1;
    }
    const double pixels = double(w) * h;
    const double cnn = (flops_per_pixel(kpcn.diffuse) + flops_per_pixel(kpcn.specular)) * pixels;
    const double mixing = flops_per_pixel(mix) * pixels;
    double conv_flops = 0;
    const mcdn_bench::Timing t = mcdn_bench::plain_onednn_conv(h, w, 48, 48, 3, 2, &conv_flops);
    const double rate = conv_flops / t.wall;  // FLOP per wall second
    const double layers_cnn =
        plain_layers_seconds(kpcn.diffuse, h, w) + plain_layers_seconds(kpcn.specular, h, w);
    const double layers_mix = plain_layers_seconds(mix, h, w);
    std::string oidn_fields;
    if (argc == 4) {
        nn::Weights weights;
        nn::Net unet;
        if (!oidn_net::read_tza(argv[3], weights, error)
            || !oidn_net::build_unet(unet, weights, error)) {
            std::fprintf(stderr, "bench_floor: %s\n", error.c_str());
            return 1;
        }
        const double oidn = flops_per_pixel(unet) * pixels;
        const double layers_oidn = plain_layers_seconds(unet, h, w);
        const double layers_oidn_as_run = plain_run_layers_seconds(unet, h, w);
        char text[320];
        std::snprintf(text, sizeof text,
                      ", \"oidn_gflop\": %.1f, \"floor_oidn_s\": %.3f, \"floor_oidn_best_s\": "
                      "%.3f, \"layers_oidn_s\": %.3f, \"layers_oidn_best_s\": %.3f, "
                      "\"layers_oidn_as_run_s\": %.3f",
                      oidn / 1e9, oidn / rate, (2 * oidn + mixing) / rate, layers_oidn,
                      2 * layers_oidn + plain_layers_seconds(mix, h, w), layers_oidn_as_run);
        oidn_fields = text;
    }
    std::printf("{\"width\": %d, \"height\": %d, \"cnn_gflop\": %.1f, \"mix_gflop\": %.1f, "
                "\"conv_gflop_per_s\": %.1f, \"conv_cpu_s\": %.3f, \"conv_wall_s\": %.3f, "
                "\"floor_cnn_s\": %.3f, \"floor_best_s\": %.3f, \"layers_cnn_s\": %.3f, "
                "\"layers_best_s\": %.3f%s}\n",
                w, h, cnn / 1e9, mixing / 1e9, rate / 1e9, t.cpu, t.wall, cnn / rate,
                (2 * cnn + mixing) / rate, layers_cnn, 2 * layers_cnn + layers_mix,
                oidn_fields.c_str());
    return 0;
}
