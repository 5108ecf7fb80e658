// The KPCN branch network (training/cnn/model.py Branch), op for op: a 3-level UNet on the
// 34 input channels whose 1×1 head predicts `iterations` softmax kernels of 5×5 per pixel
// (KPCN §4.2 eq. 9), applied one after the other to the image (5 steps of 5×5 reach the
// paper's 21×21 footprint).
#include <OpenImageIO/strutil.h>

#include "cnn/cnn_steps.h"

namespace mcdn {
namespace kpcn {

nn::Net build_branch(const std::string& prefix, int w1, int w2, int w3, int iterations,
                     int image_channels)
{
    using nn::Value;
    nn::Net net("kpcn." + prefix);
    const std::string p = prefix + ".";
    Value features = net.input("features", kInputChannels);
    Value image = net.input("image", image_channels);
    Value e1 = net.conv(features, p + "enc1", w1, 3);
    Value e2 = net.conv(net.conv(net.max_pool2(e1), p + "enc2a", w2, 3), p + "enc2b", w2, 3);
    Value b =
        net.conv(net.conv(net.max_pool2(e2), p + "bottleneck_a", w3, 3), p + "bottleneck_b", w3, 3);
    Value d2 = net.conv(net.concat({ net.upsample2(b), e2 }), p + "dec2", w2, 3);
    Value d1 = net.conv(net.concat({ net.upsample2(d2), e1 }), p + "dec1", w1, 3);
    const int taps = kKernel * kKernel;
    Value logits = net.conv(d1, p + "kernels", iterations * taps, 1, nn::Activation::none);
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
        const int w1 = dim_of(weights, p + "enc1.weight", 0);
        const int w2 = dim_of(weights, p + "enc2a.weight", 0);
        const int w3 = dim_of(weights, p + "bottleneck_a.weight", 0);
        const int head = dim_of(weights, p + "kernels.weight", 0);
        const int taps = kKernel * kKernel;
        if (w1 <= 0 || w2 <= 0 || w3 <= 0 || head <= 0 || head % taps) {
            error = OIIO::Strutil::fmt::format(
                "cnn: '{}': tensors {}enc1/enc2a/bottleneck_a/kernels.weight missing or "
                "malformed (kernels.weight needs a multiple of {} outputs)",
                path, p, taps);
            return false;
        }
        nn::Net& net = std::string(branch) == "diffuse" ? model.diffuse : model.specular;
        net = build_branch(branch, w1, w2, w3, head / taps, image_channels);
        if (!net.load(subset(weights, p), error)) {
            error = "cnn: " + error;  // names the file, the tensor and both shapes
            return false;
        }
    }
    return true;
}

}  // namespace kpcn
}  // namespace mcdn
