// PD §4.3: the mixing network h_NN. A 5x5 conv to 48 channels, two residual blocks of 3x3/48
// convs with ReLU, a 3x3 conv to (x1, x2, x3) per colour channel, then eq. 19
//   f_act = (x1 - x2) / max(x3, 1e-6), clipped to [0, 1]
// gives alpha. Trained by training/mix/train.py; its inputs are computed exactly as
// training/mix/model.py's features() (tests/mix/net_test.cpp checks the two agree):
//   0-2 HDR  signed log(1 + |x|)           3-5 DEN  signed log(1 + |y|)
//   6-8 VAR, 9-11 SURE, 12-14 sigma^2 f'(x), 15-17 ||y - x||^2: arctan(v / (y^2 + 0.01))
// (the paper's arctan of each error estimate, made relative first: see training/mix/README.md).
#include <algorithm>
#include <cmath>
#include <cstdlib>

#include <OpenImageIO/strutil.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mcdn/metrics.h"
#include "mix/mix_steps.h"
#include "nn/ops.h"

namespace mcdn {

namespace {

constexpr const char* kInputLayout = "pd-mix-1";  // model.py INPUT_LAYOUT
constexpr int kInputs = 18, kFeatures = 48;
constexpr float kFActEpsilon = 1e-6f;  // eq. 19

float signed_log1p(float v)
{
    return std::copysign(std::log1p(std::fabs(v)), v);
}

}  // namespace

std::string default_mix_weights(const std::string& denoiser)
{
    if (denoiser == "cnn" || denoiser == "oidn")
        return nn::model_file("mix_" + denoiser + ".mcdnw");
    return nn::model_file("mix.mcdnw");
}

bool load_mix_net(nn::Net& net, const std::string& path, std::string& error)
{
    using nn::Activation;
    net = nn::Net("mix");
    nn::Value x = net.input("features", kInputs);
    x = net.conv(x, "conv1", kFeatures, 5);
    for (const char* block : { "res1", "res2" }) {
        nn::Value r = net.conv(x, std::string(block) + ".conv1", kFeatures, 3);
        r = net.conv(r, std::string(block) + ".conv2", kFeatures, 3, Activation::none);
        x = net.add(x, r, Activation::relu);
    }
    net.output("raw", net.conv(x, "out", 9, 3, Activation::none));

    nn::Weights weights;
    if (!nn::read_weights(path, weights, error)) {
        error = "mix: model=net: " + error
                + " (train and export with training/mix, or pass --mix:weights=FILE)";
        return false;
    }
    const std::string tag = OIIO::Strutil::fmt::format("\"input_layout\": \"{}\"", kInputLayout);
    if (weights.metadata.find(tag) == std::string::npos) {
        error = OIIO::Strutil::fmt::format(
            "mix: '{}' is not a mixing network of input layout '{}' (its metadata lacks {}): "
            "export it with training/mix/export.py",
            path, kInputLayout, tag);
        return false;
    }
    if (!net.load(weights, error)) {
        error = "mix: '" + path + "': " + error;
        return false;
    }
    return true;
}

void net_features(const MixInputs& in, const Rect& window, nn::Tensor& f)
{
    const int w = in.x[0].width, h = in.x[0].height;
    nn::reshape(f, window.height(), window.width(), kInputs);
    // Threaded over rows (18 log/atan per pixel).
    tbb::parallel_for(tbb::blocked_range<int>(window.y0, window.y1),
                      [&](const tbb::blocked_range<int>& rows) {
                          for (int wy = rows.begin(); wy < rows.end(); ++wy) {
                              const size_t row = size_t(std::min(wy, h - 1)) * w;
                              float* px = f.pixel(wy - window.y0, 0);
                              for (int wx = window.x0; wx < window.x1; ++wx, px += kInputs) {
                                  const size_t i = row + size_t(std::min(wx, w - 1));
                                  for (int c = 0; c < 3; ++c) {
                                      const float y = in.y[c].px[i];
                                      const float scale = 1.0f / (y * y + float(kRelMseOffset));
                                      px[0 + c] = signed_log1p(in.x[c].px[i]);
                                      px[3 + c] = signed_log1p(y);
                                      px[6 + c] = std::atan(in.variance[c].px[i] * scale);
                                      px[9 + c] = std::atan(in.sure[c].px[i] * scale);
                                      px[12 + c] = std::atan(in.divergence[c].px[i] * scale);
                                      px[15 + c] = std::atan(in.residual[c].px[i] * scale);
                                  }
                              }
                          }
                      });
}

nn::Tensor net_features(const MixInputs& in)
{
    nn::Tensor f;
    net_features(in, Rect { 0, 0, in.x[0].width, in.x[0].height }, f);
    return f;
}

bool net_alpha(Plane alpha[3], const MixInputs& in, nn::Net& net, std::string& error,
               nn::Tensor* raw_out, const std::vector<Rect>& regions)
{
    // The features made a tile window at a time: no frame of 18 inputs beside the band.
    const nn::TileInputs features = [&](const Rect& window, std::vector<nn::Tensor>& inputs,
                                        std::string&) {
        inputs.resize(1);
        net_features(in, window, inputs[0]);
        return true;
    };
    std::vector<nn::Tensor> outputs;
    // Tiles of 256: the 48-channel layers' buffers follow (tile + halo)^2, and the result is
    // the same for any tile.
    nn::TileOptions tiles;
    tiles.tile_size = 256;
    tiles.regions = regions;
    if (!nn::run_tiled(net, in.x[0].height, in.x[0].width, features, outputs, error, tiles)) {
        error = "mix: model=net: " + error;
        return false;
    }
    const nn::Tensor& raw = outputs[0];
    for (int c = 0; c < 3; ++c) {
        alpha[c] = Plane(in.x[c].width, in.x[c].height);
        for (size_t i = 0; i < alpha[c].size(); ++i) {
            const float* o = raw.data.data() + i * 9;
            // Eq. 19; channel k * 3 + c is x_{k+1} of colour channel c.
            float a = (o[c] - o[3 + c]) / std::max(o[6 + c], kFActEpsilon);
            alpha[c].px[i] = a == a ? std::min(std::max(a, 0.0f), 1.0f) : 0.0f;
        }
    }
    if (raw_out)
        *raw_out = raw;
    return true;
}

}  // namespace mcdn
