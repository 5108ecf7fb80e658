// The KPCN op (lib/src/cnn): the whole op against PyTorch (training/cnn/model.py denoise) on
// a committed fixture, its properties (finite on bad inputs, tiled = untiled, the same for 1
// and 2 threads, chainable under sure) and its error messages.
#include <cmath>
#include <cstdio>
#include <fstream>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>

#include "cnn/cnn_steps.h"
#include "mcdn/cnn.h"
#include "mcdn/io.h"
#include "mcdn/sure.h"

#include "../nn/nn_test_util.h"

using namespace mcdn;
using nn_test::relative_error;

namespace {

const char* kRender = "generated/0000_interior/0000_interior_0016spp";

std::string tiny_weights()
{
    return mcdn_test::test_data("cnn/kpcn_tiny.mcdnw");
}

ImageBuf read_render(const std::string& prefix = kRender)
{
    const std::string base = mcdn_test::test_data(prefix);
    ImageBuf merged;
    EXPECT_TRUE(read_inputs(merged, { { base + ".exr", InputKind::Mean },
                                      { base + "_var.exr", InputKind::Variance },
                                      { base + "_A.exr", InputKind::HalfA },
                                      { base + "_B.exr", InputKind::HalfB } }))
        << merged.geterror();
    return merged;
}

/// The colour role of an op's result as a tensor [H, W, 3].
nn::Tensor color_tensor(const ImageBuf& buf)
{
    AovSet aovs;
    std::string error;
    EXPECT_TRUE(resolve_aovs(aovs, AovSpec {}, buf.spec(), error)) << error;
    const ROI roi = buf.roi();
    nn::Tensor t(roi.height(), roi.width(), 3);
    for (int c = 0; c < 3; ++c) {
        std::vector<float> plane(size_t(roi.width()) * roi.height());
        const int ch = aovs.channels(Role::Color)[c];
        buf.get_pixels(ROI(roi.xbegin, roi.xend, roi.ybegin, roi.yend, 0, 1, ch, ch + 1),
                       OIIO::TypeDesc::FLOAT, plane.data());
        for (size_t i = 0; i < plane.size(); ++i)
            t.data[i * 3 + c] = plane[i];
    }
    return t;
}

nn::Tensor fixture_output(const std::string& name)
{
    nn::Weights io;
    std::string error;
    EXPECT_TRUE(nn::read_weights(mcdn_test::test_data("cnn/kpcn_tiny_io.mcdnw"), io, error))
        << error;
    const nn::NamedTensor* t = io.find(name);
    EXPECT_NE(t, nullptr) << name;
    nn::Tensor out;
    if (t) {
        out = nn::Tensor(t->shape[0], t->shape[1], t->shape[2]);
        out.data = t->values;
    }
    return out;
}

CnnOptions tiny_options(int tile_size = 256)
{
    CnnOptions options;
    options.weights = tiny_weights();
    options.tile_size = tile_size;
    return options;
}

bool all_finite(const ImageBuf& buf)
{
    std::vector<float> px(buf.spec().image_pixels() * buf.nchannels());
    buf.get_pixels(buf.roi(), OIIO::TypeDesc::FLOAT, px.data());
    for (float v : px)
        if (!std::isfinite(v))
            return false;
    return true;
}

TEST(Cnn, WholeOpMatchesPyTorch)
{
    ImageBuf src = read_render();
    ImageBuf dst;
    ASSERT_TRUE(cnn(dst, src, tiny_options())) << dst.geterror();
    const double err = relative_error(color_tensor(dst), fixture_output("output.color"));
    std::printf("C++ op vs PyTorch (32x32): max relative error %.3g\n", err);
    EXPECT_LT(err, 1e-4);
}

TEST(Cnn, CutImageMatchesPyTorch)
{
    // 29 x 30: not a multiple of the alignment, so run_tiled's extension is exercised.
    ImageBuf src = read_render();
    ImageBuf cut = OIIO::ImageBufAlgo::cut(src, ROI(0, 29, 0, 30));
    ImageBuf dst;
    ASSERT_TRUE(cnn(dst, cut, tiny_options())) << dst.geterror();
    const double err = relative_error(color_tensor(dst), fixture_output("output.color_cut"));
    std::printf("C++ op vs PyTorch (29x30): max relative error %.3g\n", err);
    EXPECT_LT(err, 1e-4);
}

TEST(Cnn, TiledEqualsUntiledAndThreadsAgree)
{
    ImageBuf src = read_render();
    ImageBuf whole, tiled, one, two;
    ASSERT_TRUE(cnn(whole, src, tiny_options(256))) << whole.geterror();
    ASSERT_TRUE(cnn(tiled, src, tiny_options(8))) << tiled.geterror();
    ASSERT_TRUE(cnn(one, src, tiny_options(8), {}, 1)) << one.geterror();
    ASSERT_TRUE(cnn(two, src, tiny_options(8), {}, 2)) << two.geterror();
    const nn::Tensor w = color_tensor(whole), t = color_tensor(tiled);
    EXPECT_LT(relative_error(t, w), 1e-5);
    const nn::Tensor a = color_tensor(one), b = color_tensor(two);
    EXPECT_EQ(a.data, b.data) << "1 and 2 threads differ";
    EXPECT_EQ(a.data, t.data) << "1 thread and all threads differ";
}

TEST(Cnn, KeepsOtherChannelsAndRoi)
{
    ImageBuf src = read_render();
    ImageBuf dst;
    const ROI roi(4, 20, 8, 24);
    ASSERT_TRUE(cnn(dst, src, tiny_options(), roi)) << dst.geterror();
    ASSERT_EQ(dst.nchannels(), src.nchannels());
    const nn::Tensor in = color_tensor(src), out = color_tensor(dst);
    int changed_inside = 0, changed_outside = 0;
    for (int y = 0; y < in.height; ++y)
        for (int x = 0; x < in.width; ++x) {
            const bool inside = x >= roi.xbegin && x < roi.xend && y >= roi.ybegin && y < roi.yend;
            const bool changed = in.at(y, x, 0) != out.at(y, x, 0);
            (inside ? changed_inside : changed_outside) += changed;
        }
    EXPECT_EQ(changed_outside, 0);
    EXPECT_GT(changed_inside, 0);
    // A feature channel is untouched.
    const int albedo = src.spec().channelindex("ViewLayer.Denoising Albedo.G");
    ASSERT_GE(albedo, 0);
    EXPECT_EQ(src.getchannel(3, 5, 0, albedo), dst.getchannel(3, 5, 0, albedo));
}

TEST(Cnn, InPlaceEqualsACopy)
{
    // Tiles write their results while other tiles still read the render around them: in
    // place, the op must read a copy, never a neighbour's result.
    // In place the colour is made in a frame of its own (every channel and a ROI checked).
    ImageBuf src = read_render();
    for (const ROI roi : { ROI(), ROI(4, 20, 8, 24) }) {
        ImageBuf copy, in_place = src.copy(OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(cnn(copy, src, tiny_options(8), roi, 2)) << copy.geterror();
        ASSERT_TRUE(cnn(in_place, in_place, tiny_options(8), roi, 2)) << in_place.geterror();
        EXPECT_EQ(color_tensor(in_place).data, color_tensor(copy).data);
        const auto cmp = OIIO::ImageBufAlgo::compare(in_place, copy, 0, 0);
        EXPECT_EQ(cmp.maxerror, 0.0) << "channel " << copy.spec().channel_name(cmp.maxc);
        EXPECT_EQ(in_place.spec().channelnames, copy.spec().channelnames);
    }
}

TEST(Cnn, WorkersKeptBetweenCallsGiveTheSameResult)
{
    // cnn() hands its workers (networks and buffers) to the next call (worker_pool.h): their
    // buffers then hold another frame's values and shapes, which must not change a result.
    ImageBuf src = read_render();
    release_cnn_workers();
    ImageBuf fresh, other, again;
    ASSERT_TRUE(cnn(fresh, src, tiny_options(8), {}, 2)) << fresh.geterror();
    ROI corner = src.roi();
    corner.xend = corner.xbegin + 13;
    corner.yend = corner.ybegin + 9;
    const ImageBuf small = OIIO::ImageBufAlgo::cut(src, corner);
    ASSERT_TRUE(cnn(other, small, tiny_options(16), {}, 2)) << other.geterror();
    ASSERT_TRUE(cnn(again, src, tiny_options(8), {}, 1)) << again.geterror();
    EXPECT_EQ(color_tensor(again).data, color_tensor(fresh).data);
    release_cnn_workers();
}

TEST(Cnn, FiniteOnNanAndHugeFeatures)
{
    ImageBuf src = read_render();
    const ImageSpec& spec = src.spec();
    const char* poisoned[] = { "ViewLayer.Denoising Albedo.R",  "ViewLayer.Denoising Normal.X",
                               "ViewLayer.Denoising Depth.Z",   "ViewLayer.DiffCol.G",
                               "variance.ViewLayer.GlossDir.B", "ViewLayer.Combined.R" };
    for (int i = 0; i < 6; ++i) {
        const int ch = spec.channelindex(poisoned[i]);
        ASSERT_GE(ch, 0) << poisoned[i];
        std::vector<float> v(spec.nchannels);
        src.getpixel(3 + i, 7, v.data(), spec.nchannels);
        v[ch] = i % 2 ? 1e30f : NAN;
        src.setpixel(3 + i, 7, v.data(), spec.nchannels);
        src.getpixel(20, 3 + i, v.data(), spec.nchannels);
        v[ch] = i % 2 ? NAN : -1e30f;
        src.setpixel(20, 3 + i, v.data(), spec.nchannels);
    }
    ImageBuf dst;
    ASSERT_TRUE(cnn(dst, src, tiny_options())) << dst.geterror();
    for (float v : color_tensor(dst).data)  // the poisoned feature channels stay as they were
        ASSERT_TRUE(std::isfinite(v));
}

TEST(Cnn, ChainsUnderSure)
{
    ImageBuf src = read_render();
    Denoiser denoiser = [](ImageBuf& d, const ImageBuf& s) { return cnn(d, s, tiny_options()); };
    ImageBuf dst;
    ASSERT_TRUE(sure(dst, src, denoiser)) << dst.geterror();
    EXPECT_GE(dst.spec().channelindex("sure.R"), 0);
    EXPECT_TRUE(all_finite(dst));
    // Which denoiser made the colour, for mix to pick the network trained for it.
    EXPECT_EQ(dst.spec().get_string_attribute("mcdn:denoiser"), "cnn");
}

TEST(Cnn, WithoutSplitUsesTheSpecularNetworkOnColor)
{
    // Only the colour and its variance: the generic preset has no split here.
    ImageBuf src = read_render();
    const int first = src.spec().channelindex("ViewLayer.Combined.R");
    const int var = src.spec().channelindex("variance.ViewLayer.Combined.R");
    const std::vector<int> order = { first, first + 1, first + 2, var, var + 1, var + 2 };
    const std::vector<std::string> names = {
        "R", "G", "B", "variance.R", "variance.G", "variance.B"
    };
    ImageBuf color = OIIO::ImageBufAlgo::channels(src, 6, order, {}, names);
    CnnOptions options = tiny_options();
    options.aovs.preset = "generic";
    ImageBuf dst;
    ASSERT_TRUE(cnn(dst, color, options)) << dst.geterror();
    EXPECT_TRUE(all_finite(dst));
}

TEST(Cnn, ErrorsNameTheFile)
{
    ImageBuf src = read_render();
    CnnOptions options;
    options.weights = "/nonexistent/kpcn.mcdnw";
    ImageBuf dst;
    EXPECT_FALSE(cnn(dst, src, options));
    const std::string missing = dst.geterror();
    EXPECT_NE(missing.find("/nonexistent/kpcn.mcdnw"), std::string::npos) << missing;

    // The mixing network's fixture is a weights file, but not a KPCN.
    options.weights = mcdn_test::test_data("nn/tiny_net.mcdnw");
    ImageBuf dst2;
    EXPECT_FALSE(cnn(dst2, src, options));
    const std::string foreign = dst2.geterror();
    EXPECT_NE(foreign.find("input layout"), std::string::npos) << foreign;

    // A KPCN file with a tensor of the wrong shape: the tensor is named.
    nn::Weights weights;
    std::string error;
    ASSERT_TRUE(nn::read_weights(tiny_weights(), weights, error)) << error;
    for (auto& t : weights.tensors)
        if (t.name == "specular.dec2.weight") {
            t.shape[1] += 1;
            t.values.resize(size_t(t.shape[0]) * t.shape[1] * t.shape[2] * t.shape[3]);
        }
    const std::string bad = mcdn_test::temp_dir("cnn_errors") + "/bad.mcdnw";
    ASSERT_TRUE(nn::write_weights(bad, weights, error)) << error;
    options.weights = bad;
    ImageBuf dst3;
    EXPECT_FALSE(cnn(dst3, src, options));
    const std::string message = dst3.geterror();
    EXPECT_NE(message.find("specular.dec2"), std::string::npos) << message;
    EXPECT_NE(message.find("bad.mcdnw"), std::string::npos) << message;
}

TEST(Cnn, CommittedModelDenoises)
{
    // models/kpcn.mcdnw (training/cnn/export.py): loads, and lowers the error of the fixture
    // render against its reference (a property, not a quality benchmark: bench_cnn is that).
    const std::string weights = std::string(MCDN_SOURCE_DIR) + "/models/kpcn.mcdnw";
    if (!OIIO::Filesystem::exists(weights))
        GTEST_SKIP() << weights << " absent: train and export with training/cnn";
    ImageBuf src = read_render();
    CnnOptions options;
    options.weights = weights;
    ImageBuf dst;
    ASSERT_TRUE(cnn(dst, src, options)) << dst.geterror();
    ImageBuf ref;
    ASSERT_TRUE(
        read_image(ref, mcdn_test::test_data("generated/0000_interior/0000_interior_ref.exr")))
        << ref.geterror();
    const nn::Tensor noisy = color_tensor(src), denoised = color_tensor(dst),
                     reference = color_tensor(ref);
    double noisy_error = 0, denoised_error = 0;  // relMSE
    for (size_t i = 0; i < reference.data.size(); ++i) {
        const double r = reference.data[i], scale = r * r + 0.01;
        ASSERT_TRUE(std::isfinite(denoised.data[i]));
        noisy_error += (noisy.data[i] - r) * (noisy.data[i] - r) / scale;
        denoised_error += (denoised.data[i] - r) * (denoised.data[i] - r) / scale;
    }
    std::printf("fixture render 16 spp relMSE: noisy %.5f, KPCN %.5f\n",
                noisy_error / reference.data.size(), denoised_error / reference.data.size());
    EXPECT_LT(denoised_error, 0.5 * noisy_error);
}

TEST(Cnn, DefaultWeightsPathHonoursEnvironment)
{
    setenv("MCDN_MODELS", "/some/dir", 1);
    EXPECT_EQ(default_cnn_weights(), "/some/dir/kpcn.mcdnw");
    unsetenv("MCDN_MODELS");
    EXPECT_NE(default_cnn_weights().find("kpcn.mcdnw"), std::string::npos);
}

/// The AOV set of `image` with only the channels of `roles` (the others dropped).
AovSet aovs_of(const ImageBuf& image, const std::vector<Role>& roles)
{
    AovSet aovs;
    std::string error;
    EXPECT_TRUE(resolve_aovs(aovs, AovSpec {}, image.spec(), error)) << error;
    std::vector<int> order;
    for (Role r : roles)
        for (int c : aovs.channels(r))
            order.push_back(c);
    const ImageBuf cut = OIIO::ImageBufAlgo::channels(image, int(order.size()), order);
    EXPECT_TRUE(resolve_aovs(aovs, AovSpec {}, cut.spec(), error)) << error;
    return aovs;
}

TEST(Cnn, ColourAlbedoNormalAloneGetTheirOwnModel)
{
    // The colour + albedo + normal model where the frame has neither the colour's variance
    // nor the light split and the models directory holds it; kpcn.mcdnw otherwise.
    const std::string dir = mcdn_test::temp_dir("cnn_default_weights");
    std::ofstream(dir + "/kpcn.mcdnw") << "";
    const ImageBuf src = read_render();
    const AovSet can = aovs_of(src, { Role::Color, Role::Albedo, Role::Normal, Role::Depth });
    const AovSet variance = aovs_of(src, { Role::Color, Role::ColorVariance, Role::Albedo });
    AovSet all;
    std::string error;
    ASSERT_TRUE(resolve_aovs(all, AovSpec {}, src.spec(), error)) << error;
    ASSERT_TRUE(can.has(Role::Depth) && !can.has(Role::ColorVariance));
    setenv("MCDN_MODELS", dir.c_str(), 1);
    EXPECT_EQ(default_cnn_weights(&can), dir + "/kpcn.mcdnw");  // not installed
    std::ofstream(dir + "/kpcn_can.mcdnw") << "";
    EXPECT_EQ(default_cnn_weights(&can), dir + "/kpcn_can.mcdnw");
    EXPECT_EQ(default_cnn_weights(&variance), dir + "/kpcn.mcdnw");
    EXPECT_EQ(default_cnn_weights(&all), dir + "/kpcn.mcdnw");
    EXPECT_EQ(default_cnn_weights(), dir + "/kpcn.mcdnw");
    unsetenv("MCDN_MODELS");
}

TEST(Cnn, AModelTrainedWithoutDepthReadsNone)
{
    // Weights whose metadata says "reads_depth": false (export.py, a run that always dropped
    // depth) give the same result whatever the depth pass holds; others do not.
    nn::Weights weights;
    std::string error;
    ASSERT_TRUE(nn::read_weights(tiny_weights(), weights, error)) << error;
    ASSERT_EQ(weights.metadata.back(), '}');
    weights.metadata.insert(weights.metadata.size() - 1, ", \"reads_depth\": false");
    const std::string without = mcdn_test::temp_dir("cnn_no_depth") + "/no_depth.mcdnw";
    ASSERT_TRUE(nn::write_weights(without, weights, error)) << error;
    const ImageBuf src = read_render();
    ImageBuf moved;
    moved.copy(src);
    AovSet aovs;
    ASSERT_TRUE(resolve_aovs(aovs, AovSpec {}, src.spec(), error)) << error;
    ASSERT_TRUE(aovs.has(Role::Depth));
    const int depth = aovs.channels(Role::Depth)[0];
    // The depth squared (the op scales depth to the frame's range: an affine change is none).
    ASSERT_TRUE(
        OIIO::ImageBufAlgo::pow(moved, moved, 2.0f,
                                OIIO::ROI(src.roi().xbegin, src.roi().xend, src.roi().ybegin,
                                          src.roi().yend, 0, 1, depth, depth + 1)))
        << moved.geterror();
    for (const std::string& path : { without, tiny_weights() }) {
        CnnOptions options;
        options.weights = path;
        ImageBuf a, b;
        ASSERT_TRUE(cnn(a, src, options)) << a.geterror();
        ASSERT_TRUE(cnn(b, moved, options)) << b.geterror();
        const float difference = relative_error(color_tensor(a), color_tensor(b));
        if (path == without)
            EXPECT_EQ(difference, 0.0f);
        else
            EXPECT_GT(difference, 1e-4f);
    }
}

}  // namespace
