// The KPCN branch network (training/cnn/model.py Branch), op for op: a UNet on the 34 input
// channels — two 3×3 convolutions a level (one at full resolution), max pooling down, nearest
// upsampling and concatenation up — whose 1×1 head predicts `iterations` softmax kernels of
// 5×5 per pixel (KPCN §4.2 eq. 9), applied one after the other to the image (5 steps of 5×5
// reach the paper's 21×21 footprint). Tensor names as model.py's layer_names: 3 levels are
// enc1, enc2a/b, bottleneck_a/b, dec2, dec1; each level more adds enc<l>a/b and dec<l>.
#include <OpenImageIO/strutil.h>

#include <algorithm>

#include "cnn/cnn_steps.h"

namespace mcdn {
namespace kpcn {

nn::Net build_branch(const std::string& prefix, const std::vector<int>& widths, int iterations,
                     int image_channels)
{
    using nn::Value;
    using OIIO::Strutil::fmt::format;
    nn::Net net("kpcn." + prefix);
    const std::string p = prefix + ".";
    const int levels = int(widths.size());
    Value features = net.input("features", kInputChannels);
    Value image = net.input("image", image_channels);
    std::vector<Value> skips { net.conv(features, p + "enc1", widths[0], 3) };
    for (int level = 1; level + 1 < levels; ++level) {
        const std::string name = format("{}enc{}", p, level + 1);
        skips.push_back(
            net.conv(net.conv(net.max_pool2(skips.back()), name + "a", widths[level], 3),
                     name + "b", widths[level], 3));
    }
    Value d = net.conv(net.conv(net.max_pool2(skips.back()), p + "bottleneck_a", widths.back(), 3),
                       p + "bottleneck_b", widths.back(), 3);
    for (int level = levels - 2; level >= 0; --level)
        d = net.conv(net.concat({ net.upsample2(d), skips[size_t(level)] }),
                     format("{}dec{}", p, level + 1), widths[size_t(level)], 3);
    const int taps = kKernel * kKernel;
    Value logits = net.conv(d, p + "kernels", iterations * taps, 1, nn::Activation::none);
    for (int i = 0; i < iterations; ++i)
        image = net.apply_kernel(net.slice(logits, i * taps, taps), image, kKernel);
    net.output("denoised", image);
    return net;
}

namespace {

/// The dimension `dim` of tensor `name`, or -1.
int dim_of(const nn::Weights& weights, const std::string& name, size_t dim)
{
    const nn::NamedTensor* t = weights.find(name);
    return t && t->shape.size() > dim ? t->shape[dim] : -1;
}

/// The tensors whose names start with `prefix`.
nn::Weights subset(const nn::Weights& weights, const std::string& prefix)
{
    nn::Weights out;
    out.path = weights.path;
    out.version = weights.version;
    out.metadata = weights.metadata;
    for (const auto& t : weights.tensors)
        if (OIIO::Strutil::starts_with(t.name, prefix))
            out.tensors.push_back(t);
    return out;
}

}  // namespace

bool load_model(Model& model, const std::string& path, std::string& error, int image_channels)
{
    nn::Weights weights;
    if (!nn::read_weights(path, weights, error)) {
        error =
            "cnn: " + error + " (train and export with training/cnn, or pass --cnn:weights=FILE)";
        return false;
    }
    const std::string tag = OIIO::Strutil::fmt::format("\"input_layout\": \"{}\"", kInputLayout);
    if (weights.metadata.find(tag) == std::string::npos) {
        error = OIIO::Strutil::fmt::format(
            "cnn: '{}' is not a KPCN model of input layout '{}' (its metadata lacks {}): "
            "export it with training/cnn/export.py",
            path, kInputLayout, tag);
        return false;
    }
    model.reads_depth = weights.metadata.find("\"reads_depth\": false") == std::string::npos;
    for (const char* branch : { "diffuse", "specular" }) {
        const std::string p = std::string(branch) + ".";
        // The widths by level: enc1, enc2a, enc3a, ... as far as they go, then the bottleneck.
        std::vector<int> widths { dim_of(weights, p + "enc1.weight", 0) };
        for (int level = 2;; ++level) {
            const int w =
                dim_of(weights, OIIO::Strutil::fmt::format("{}enc{}a.weight", p, level), 0);
            if (w <= 0)
                break;
            widths.push_back(w);
        }
        widths.push_back(dim_of(weights, p + "bottleneck_a.weight", 0));
        const int head = dim_of(weights, p + "kernels.weight", 0);
        const int taps = kKernel * kKernel;
        if (widths.size() < 3 || *std::min_element(widths.begin(), widths.end()) <= 0 || head <= 0
            || head % taps) {
            error = OIIO::Strutil::fmt::format(
                "cnn: '{}': tensors {}enc1/enc2a/bottleneck_a/kernels.weight missing or "
                "malformed (kernels.weight needs a multiple of {} outputs)",
                path, p, taps);
            return false;
        }
        nn::Net& net = std::string(branch) == "diffuse" ? model.diffuse : model.specular;
        net = build_branch(branch, widths, head / taps, image_channels);
        if (!net.load(subset(weights, p), error)) {
            error = "cnn: " + error;  // names the file, the tensor and both shapes
            return false;
        }
    }
    return true;
}

}  // namespace kpcn
}  // namespace mcdn
