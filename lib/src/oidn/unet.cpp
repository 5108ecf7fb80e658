// OIDN's UNet on our engine (oidn_steps.h build_unet) and its HDR transfer function.
#include <cmath>

#include <OpenImageIO/strutil.h>

#include "oidn/oidn_steps.h"

namespace mcdn {
namespace oidn_net {

using OIIO::Strutil::fmt::format;

bool build_unet(nn::Net& net, const nn::Weights& weights, std::string& error)
{
    // Every convolution's output channels from its weight's shape [out, in, 3, 3].
    auto out_channels = [&](const std::string& name) {
        const nn::NamedTensor* w = weights.find(name + ".weight");
        return w && w->shape.size() == 4 ? w->shape[0] : -1;
    };
    const nn::NamedTensor* first = weights.find("enc_conv0.weight");
    if (!first || first->shape.size() != 4) {
        error = format("{}: no enc_conv0.weight [out, in, 3, 3]: not an OIDN UNet", weights.path);
        return false;
    }
    net = nn::Net("oidn");
    const nn::Value input = net.input("color_albedo_normal", first->shape[1]);
    bool shapes_known = true;
    auto conv = [&](nn::Value x, const std::string& name) {
        const int channels = out_channels(name);
        shapes_known &= channels > 0;
        return net.conv(x, name, std::max(channels, 1), 3);
    };
    nn::Value x = conv(input, "enc_conv0");
    nn::Value pool[5];
    for (int level = 1; level <= 4; ++level) {
        x = net.max_pool2(conv(x, format("enc_conv{}", level)));
        pool[level] = x;
    }
    x = conv(conv(x, "enc_conv5a"), "enc_conv5b");
    for (int level = 4; level >= 2; --level) {
        x = net.concat({ net.upsample2(x), pool[level - 1] });
        x = conv(conv(x, format("dec_conv{}a", level)), format("dec_conv{}b", level));
    }
    x = net.concat({ net.upsample2(x), input });
    x = conv(conv(x, "dec_conv1a"), "dec_conv1b");
    net.output("color", conv(x, "dec_conv0"));
    if (!shapes_known) {
        error = format("{}: a convolution of OIDN's UNet is missing (expects enc_conv0-4, "
                       "enc_conv5a/b, dec_conv4a/b-1a/b, dec_conv0)",
                       weights.path);
        return false;
    }
    return net.load(weights, error);
}

namespace {

// The PU curve's fit (OIDN's constants): linear near 0, a power law, then a logarithm.
constexpr float kA = 1.41283765e+03f, kB = 1.64593172e+00f, kC = 4.31384981e-01f,
                kD = -2.94139609e-03f, kE = 1.92653254e-01f, kF = 6.26026094e-03f,
                kG = 9.98620152e-01f;
constexpr float kY0 = 1.57945760e-06f, kY1 = 3.22087631e-02f;  // where the pieces meet
constexpr float kX0 = 2.23151711e-03f, kX1 = 3.70974749e-01f;  // the same, encoded
constexpr float kHdrMax = 65504.0f;                            // what encodes to 1

float pu(float y)
{
    return y <= kY0 ? kA * y : y <= kY1 ? kB * std::pow(y, kC) + kD : kE * std::log(y + kF) + kG;
}

float pu_inverse_raw(float x)
{
    return x <= kX0   ? x / kA
           : x <= kX1 ? std::pow((x - kD) / kB, 1.0f / kC)
                      : std::exp((x - kG) / kE) - kF;
}

const float kNorm = 1.0f / pu(kHdrMax);

}  // namespace

float pu_forward(float y)
{
    return pu(y) * kNorm;
}

float pu_inverse(float x)
{
    return pu_inverse_raw(x / kNorm);
}

float srgb_forward(float y)
{
    return y <= 0.0031308f ? 12.92f * y : 1.055f * std::pow(y, 1.0f / 2.4f) - 0.055f;
}

float srgb_inverse(float x)
{
    return x <= 0.04045f ? x / 12.92f : std::pow((x + 0.055f) / 1.055f, 2.4f);
}

}  // namespace oidn_net
}  // namespace mcdn
