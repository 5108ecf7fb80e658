// The mixing network (PD §4.3): the C++ forward pass against PyTorch's on a fixture, its
// error messages, and the mix's properties on real generated crops with our NFOR.
#include <cstdio>
#include <cstdlib>

#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/sure.h"
#include "mix/mix_steps.h"

#include "../nn/nn_test_util.h"

using namespace mcdn;
using nn_test::relative_error;

namespace {

nn::Tensor to_tensor(const nn::NamedTensor& t)
{
    nn::Tensor out(t.shape[0], t.shape[1], t.shape[2]);
    out.data = t.values;
    return out;
}

Plane channel_plane(const nn::Tensor& t, int c)
{
    Plane p(t.width, t.height);
    for (size_t i = 0; i < p.size(); ++i)
        p.px[i] = t.data[i * t.channels + c];
    return p;
}

nn::Tensor alpha_tensor(const Plane alpha[3])
{
    nn::Tensor t(alpha[0].height, alpha[0].width, 3);
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < alpha[c].size(); ++i)
            t.data[i * 3 + c] = alpha[c].px[i];
    return t;
}

double weights_checksum(const nn::Weights& w)
{
    double sum = 0;
    for (const nn::NamedTensor& t : w.tensors)
        for (float v : t.values)
            sum += std::abs(double(v));
    return sum;
}

}  // namespace

TEST(MixNet, MatchesPyTorch)
{
    // tests/data/mix/mix_net_io.mcdnw: made by training/mix/export.py from models/mix.mcdnw.
    nn::Weights io, weights;
    std::string error;
    const std::string path = default_mix_weights();
    ASSERT_TRUE(nn::read_weights(mcdn_test::test_data("mix/mix_net_io.mcdnw"), io, error)) << error;
    ASSERT_TRUE(nn::read_weights(path, weights, error)) << error;
    const std::string key = "\"weights_checksum\": ";
    size_t at = io.metadata.find(key);
    ASSERT_NE(at, std::string::npos);
    const double checksum = std::atof(io.metadata.c_str() + at + key.size());
    ASSERT_NEAR(weights_checksum(weights), checksum, 1e-6 * checksum)
        << path << " is not the network the fixture was made with: rerun training/mix/export.py";

    MixInputs in;
    const char* names[] = { "x", "y", "variance", "sure", "divergence", "residual" };
    Plane* planes[] = { in.x, in.y, in.variance, in.sure, in.divergence, in.residual };
    for (int k = 0; k < 6; ++k) {
        const nn::Tensor t = to_tensor(*io.find(std::string("input.") + names[k]));
        for (int c = 0; c < 3; ++c)
            planes[k][c] = channel_plane(t, c);
    }
    nn::Net net;
    ASSERT_TRUE(load_mix_net(net, path, error)) << error;
    const double feature_error =
        relative_error(net_features(in), to_tensor(*io.find("output.features")));
    Plane alpha[3];
    nn::Tensor raw;
    ASSERT_TRUE(net_alpha(alpha, in, net, error, &raw)) << error;
    const double raw_error = relative_error(raw, to_tensor(*io.find("output.raw")));
    const nn::Tensor expected_alpha = to_tensor(*io.find("output.alpha"));
    const double alpha_error = relative_error(alpha_tensor(alpha), expected_alpha);
    std::printf("C++ vs PyTorch, max relative error: features %.3g, raw outputs %.3g, alpha %.3g\n",
                feature_error, raw_error, alpha_error);
    EXPECT_LT(feature_error, 1e-5);
    EXPECT_LT(raw_error, 1e-4);
    EXPECT_LT(alpha_error, 1e-4);
}

// net_alpha makes the features a tile window at a time (no frame of 18 inputs): a window
// that reaches past the frame repeats its last row and column, as run_tiled extends the
// frame, and the network's outputs are those of the whole features run at run_tiled's
// default tile, bit for bit.
TEST(MixNet, FeaturesMadePerTileEqualTheWholeFrames)
{
    nn::Weights io;
    std::string error;
    ASSERT_TRUE(nn::read_weights(mcdn_test::test_data("mix/mix_net_io.mcdnw"), io, error)) << error;
    MixInputs in;
    const char* names[] = { "x", "y", "variance", "sure", "divergence", "residual" };
    Plane* planes[] = { in.x, in.y, in.variance, in.sure, in.divergence, in.residual };
    // The fixture's inputs repeated to a frame of several tiles (a partial last one).
    const int w = 300, h = 280;
    for (int k = 0; k < 6; ++k) {
        const nn::Tensor t = to_tensor(*io.find(std::string("input.") + names[k]));
        for (int c = 0; c < 3; ++c) {
            const Plane small = channel_plane(t, c);
            planes[k][c] = Plane(w, h);
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x)
                    planes[k][c].px[size_t(y) * w + x] =
                        small.px[size_t(y % small.height) * small.width + x % small.width];
        }
    }
    const nn::Tensor whole = net_features(in);
    const Rect window { w / 2, h / 3, w + 5, h + 7 };
    nn::Tensor part;
    net_features(in, window, part);
    ASSERT_EQ(part.width, window.width());
    ASSERT_EQ(part.height, window.height());
    for (int y = window.y0; y < window.y1; ++y)
        for (int x = window.x0; x < window.x1; ++x)
            for (int c = 0; c < whole.channels; ++c)
                ASSERT_EQ(part.pixel(y - window.y0, x - window.x0)[c],
                          whole.pixel(std::min(y, h - 1), std::min(x, w - 1))[c])
                    << x << "," << y << " input " << c;

    nn::Net net;
    ASSERT_TRUE(load_mix_net(net, default_mix_weights(), error)) << error;
    Plane alpha[3];
    nn::Tensor raw;
    ASSERT_TRUE(net_alpha(alpha, in, net, error, &raw)) << error;
    std::vector<nn::Tensor> outputs;
    ASSERT_TRUE(nn::run_tiled(net, { whole }, outputs, error)) << error;
    ASSERT_EQ(raw.data.size(), outputs[0].data.size());
    EXPECT_EQ(raw.data, outputs[0].data);
}

TEST(MixNet, MissingOrWrongWeightsSayWhatToDo)
{
    nn::Net net;
    std::string error;
    EXPECT_FALSE(load_mix_net(net, "/nonexistent/mix.mcdnw", error));
    EXPECT_NE(error.find("/nonexistent/mix.mcdnw"), std::string::npos) << error;
    EXPECT_NE(error.find("training/mix"), std::string::npos) << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;

    error.clear();
    const std::string other = mcdn_test::test_data("nn/tiny_net.mcdnw");
    EXPECT_FALSE(load_mix_net(net, other, error));
    EXPECT_NE(error.find("tiny_net.mcdnw"), std::string::npos) << error;
    EXPECT_NE(error.find("input layout"), std::string::npos) << error;
}

namespace {

// A generated crop (tests/data/generated, Blender Cycles 32x32) at `spp`: NFOR, SURE (K=1)
// and the mix; errors against the reference.
struct CropErrors {
    Metrics render, denoised, mixed;
};

/// One level of a generated crop: the render with its variance and halves.
bool read_level(ImageBuf& src, const std::string& crop, int spp)
{
    char level[32];
    std::snprintf(level, sizeof level, "_%04dspp", spp);
    const std::string stem = mcdn_test::test_data("generated/" + crop + "/" + crop + level);
    return read_inputs(src, { { stem + ".exr", InputKind::Mean },
                              { stem + "_var.exr", InputKind::Variance },
                              { stem + "_A.exr", InputKind::HalfA },
                              { stem + "_B.exr", InputKind::HalfB } });
}

/// The render with NFOR's output and its SURE (K = 1): what mix reads.
bool nfor_with_sure(ImageBuf& with_sure, const ImageBuf& src)
{
    Denoiser denoiser = [](ImageBuf& dst, const ImageBuf& s) { return nfor(dst, s); };
    return sure(with_sure, src, denoiser);
}

bool run_crop(CropErrors& out, const std::string& crop, int spp, MixOptions options,
              std::string& error)
{
    ImageBuf src, ref;
    if (!read_level(src, crop, spp)
        || !read_image(ref, mcdn_test::test_data("generated/" + crop + "/" + crop + "_ref.exr"))) {
        error = src.geterror() + ref.geterror();
        return false;
    }
    ImageBuf with_sure, mixed;
    if (!nfor_with_sure(with_sure, src) || !mix(mixed, with_sure, options)) {
        error = with_sure.geterror() + mixed.geterror();
        return false;
    }
    auto rgb = [](const ImageBuf& b) {
        return std::vector<int> { b.spec().channelindex("ViewLayer.Combined.R"),
                                  b.spec().channelindex("ViewLayer.Combined.G"),
                                  b.spec().channelindex("ViewLayer.Combined.B") };
    };
    MetricsOptions mo;
    mo.reference_channels = rgb(ref);
    const std::pair<Metrics*, const ImageBuf*> runs[] = { { &out.render, &src },
                                                          { &out.denoised, &with_sure },
                                                          { &out.mixed, &mixed } };
    for (auto [m, image] : runs) {
        mo.image_channels = rgb(*image);
        if (!compute_metrics(*m, *image, ref, mo, error))
            return false;
    }
    return true;
}

}  // namespace

TEST(MixNet, DeterministicAndFinite)
{
    ImageBuf src, with_sure;
    ASSERT_TRUE(read_level(src, "0003_bump", 16)) << src.geterror();
    ASSERT_TRUE(nfor_with_sure(with_sure, src)) << with_sure.geterror();
    MixOptions options;
    options.model = MixOptions::Model::Net;
    options.output_alpha = true;
    ImageBuf one, all;
    ASSERT_TRUE(mix(one, with_sure, options, {}, 1)) << one.geterror();
    ASSERT_TRUE(mix(all, with_sure, options, {}, 0)) << all.geterror();
    std::vector<float> a(one.spec().image_pixels() * one.nchannels()), b(a.size());
    one.get_pixels(one.roi(), OIIO::TypeFloat, a.data());
    all.get_pixels(all.roi(), OIIO::TypeFloat, b.data());
    EXPECT_EQ(a, b);
    for (float v : a)
        ASSERT_TRUE(std::isfinite(v));
}

TEST(MixNet, PicksTheNetworkOfTheDenoiserThatMadeTheFrame)
{
    // One network per denoiser (PD §5.3): the nfor and cnn ops name themselves in
    // "mcdn:denoiser", sure keeps it, and mix with no weights file given takes that
    // denoiser's network; NFOR's for a denoiser it does not know.
    auto file = [](const std::string& path) { return path.substr(path.find_last_of('/') + 1); };
    EXPECT_EQ(file(default_mix_weights("cnn")), "mix_cnn.mcdnw");
    EXPECT_EQ(file(default_mix_weights("oidn")), "mix_oidn.mcdnw");
    for (const char* other : { "nfor", "", "blur" })
        EXPECT_EQ(file(default_mix_weights(other)), "mix.mcdnw") << other;

    ImageBuf src, with_sure;
    ASSERT_TRUE(read_level(src, "0003_bump", 16)) << src.geterror();
    ASSERT_TRUE(nfor_with_sure(with_sure, src)) << with_sure.geterror();
    EXPECT_EQ(with_sure.spec().get_string_attribute("mcdn:denoiser"), "nfor");
    auto mixed = [&](const std::string& weights) {
        MixOptions o;
        o.model = MixOptions::Model::Net;
        o.weights = weights;
        ImageBuf z;
        EXPECT_TRUE(mix(z, with_sure, o)) << z.geterror();
        std::vector<float> px(z.spec().image_pixels() * z.nchannels());
        z.get_pixels(z.roi(), OIIO::TypeFloat, px.data());
        return px;
    };
    const std::vector<float> nfor_net = mixed(default_mix_weights("nfor"));
    const std::vector<float> cnn_net = mixed(default_mix_weights("cnn"));
    EXPECT_NE(nfor_net, cnn_net);  // else this test could not tell which one ran
    EXPECT_EQ(mixed(""), nfor_net);
    with_sure.specmod().attribute("mcdn:denoiser", "cnn");
    EXPECT_EQ(mixed(""), cnn_net);
}

TEST(MixNet, AlphaIsAtLeastTheAnalyticModels)
{
    // MixOptions::analytic_floor: before the outlier floor and the t-test (both off here),
    // alpha = max(network, analytic eq. 9), channel by channel.
    ImageBuf src, with_sure;
    ASSERT_TRUE(read_level(src, "0003_bump", 4)) << src.geterror();
    ASSERT_TRUE(nfor_with_sure(with_sure, src)) << with_sure.geterror();
    auto alpha_of = [&](MixOptions::Model model, bool analytic_floor) {
        MixOptions o;
        o.model = model;
        o.analytic_floor = analytic_floor;
        o.t_test = false;
        o.outlier_relative_variance = o.drop_relative_variance = 0;
        o.output_alpha = true;
        ImageBuf z;
        EXPECT_TRUE(mix(z, with_sure, o)) << z.geterror();
        std::vector<float> alpha;
        for (const char* name : { "mix.alpha.R", "mix.alpha.G", "mix.alpha.B" })
            for (OIIO::ImageBuf::ConstIterator<float> it(z); !it.done(); ++it)
                alpha.push_back(it[z.spec().channelindex(name)]);
        return alpha;
    };
    const std::vector<float> net = alpha_of(MixOptions::Model::Net, false);
    const std::vector<float> analytic = alpha_of(MixOptions::Model::Analytic, false);
    const std::vector<float> both = alpha_of(MixOptions::Model::Net, true);
    ASSERT_EQ(both.size(), net.size());
    int raised = 0;
    for (size_t i = 0; i < both.size(); ++i) {
        ASSERT_EQ(both[i], std::max(net[i], analytic[i])) << i;
        raised += analytic[i] > net[i];
    }
    EXPECT_GT(raised, 0);  // the fixture has pixels where the floor acts
}

TEST(MixNet, CloseToTheBetterInputOnGeneratedCrops)
{
    // PD §4: at every sample count the mix should be about as good as the better of render
    // and denoised image. Issue 5's target is RMSE <= 1.02 x the better. With the floors of
    // MixOptions (the analytic model's alpha, the outlier floor) and the network of models/
    // (see its README) all 9 inputs meet it (at most 1.002x since 30 Nov, 1.016x with the
    // network before; without the analytic floor 0003_bump 4 spp was at 1.06x; with the
    // outlier floor's first threshold alone 0000_interior 64 spp was at 1.27x; the previous
    // network without any floor kept render fireflies on 0007_fine 16 spp: 2.29x). The bounds leave
    // room for small numerical changes upstream (NFOR, SURE) but catch a kept firefly or a network
    // that keeps too much render: never worse than the render, at most 1.10x the better input
    // anywhere, 1.03x on average.
    MixOptions options;
    options.model = MixOptions::Model::Net;
    double sum_ratio = 0;
    int n = 0;
    for (const char* crop : { "0000_interior", "0003_bump", "0007_fine" })
        for (int spp : { 4, 16, 64 }) {
            CropErrors e;
            std::string error;
            ASSERT_TRUE(run_crop(e, crop, spp, options, error)) << error;
            const double better = std::min(e.render.rmse, e.denoised.rmse);
            const double ratio = e.mixed.rmse / better;
            std::printf(
                "%-14s %3d spp  RMSE render %.4f  NFOR %.4f  mix(net) %.4f  (%.3fx the better)\n",
                crop, spp, e.render.rmse, e.denoised.rmse, e.mixed.rmse, ratio);
            EXPECT_LE(e.mixed.rmse, e.render.rmse) << crop << " " << spp;
            EXPECT_LE(ratio, 1.10) << crop << " " << spp;
            sum_ratio += ratio;
            ++n;
        }
    EXPECT_LE(sum_ratio / n, 1.03);
}
