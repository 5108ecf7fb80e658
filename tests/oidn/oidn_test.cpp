// The oidn op (lib/src/oidn): our reader of OIDN's tensor archives on a tiny archive this
// test writes itself (every CI run, no OIDN file needed), the UNet on our engine against the
// engine's plain reference loops, the op's properties (threads, tiles, bands, errors), and,
// where ../shared holds OIDN's published weights, the published measurements reproduced.
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <unistd.h>
#include <fstream>
#include <functional>
#include <random>

#include <Imath/half.h>
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/chain.h"
#include "mcdn/choose.h"
#include "mcdn/denoise.h"
#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn/oidn.h"
#include "mcdn/stages.h"
#include "oidn/oidn_steps.h"

#include "mcdn_test.h"

using namespace mcdn;

namespace {

const std::string kPeers = std::string(MCDN_SHARED_DATA) + "/../peers/oidn";

// The UNet's convolutions and the input channels of each (OIDN's layout, channel counts
// shrunk to `width`): the skip joins add pool3/2/1's and the input's channels.
std::vector<std::pair<std::string, std::array<int, 2>>> tiny_unet(int inputs, int width)
{
    const int w = width;
    return { { "enc_conv0", { w, inputs } }, { "enc_conv1", { w, w } },
             { "enc_conv2", { w, w } },      { "enc_conv3", { w, w } },
             { "enc_conv4", { w, w } },      { "enc_conv5a", { w, w } },
             { "enc_conv5b", { w, w } },     { "dec_conv4a", { w, 2 * w } },
             { "dec_conv4b", { w, w } },     { "dec_conv3a", { w, 2 * w } },
             { "dec_conv3b", { w, w } },     { "dec_conv2a", { w, 2 * w } },
             { "dec_conv2b", { w, w } },     { "dec_conv1a", { w, w + inputs } },
             { "dec_conv1b", { w, w } },     { "dec_conv0", { 3, w } } };
}

void put(std::string& bytes, uint64_t value, int size)
{
    for (int i = 0; i < size; ++i)
        bytes.push_back(char(value >> (8 * i) & 0xff));
}

// A tensor archive in OIDN's layout (oidn_steps.h read_tza), written here: weights in half
// floats, biases in floats, random values scaled so that activations stay O(1).
nn::Weights write_tiny_tza(const std::string& path, int inputs, int width, uint32_t seed)
{
    std::mt19937 random(seed);
    std::normal_distribution<float> normal(0.0f, 1.0f);
    nn::Weights expected;
    std::string data, table;
    put(table, 0, 4);  // the count, set below
    uint32_t count = 0;
    for (const auto& [name, shape] : tiny_unet(inputs, width)) {
        for (bool weight : { true, false }) {
            nn::NamedTensor t;
            t.name = name + (weight ? ".weight" : ".bias");
            t.shape = weight ? std::vector<int> { shape[0], shape[1], 3, 3 }
                             : std::vector<int> { shape[0] };
            const size_t n = weight ? size_t(shape[0]) * shape[1] * 9 : size_t(shape[0]);
            const float scale = weight ? std::sqrt(2.0f / (9.0f * shape[1])) : 0.05f;
            while (data.size() % 64)
                data.push_back(0);
            const uint64_t offset = 16 + data.size();
            for (size_t i = 0; i < n; ++i) {
                const float v = normal(random) * scale;
                if (weight) {
                    const Imath::half h(v);
                    put(data, h.bits(), 2);
                    t.values.push_back(float(h));
                } else {
                    uint32_t bits;
                    std::memcpy(&bits, &v, 4);
                    put(data, bits, 4);
                    t.values.push_back(v);
                }
            }
            put(table, t.name.size(), 2);
            table += t.name;
            put(table, t.shape.size(), 1);
            for (int d : t.shape)
                put(table, uint64_t(d), 4);
            table += weight ? "oihw" : "x";
            table += weight ? "h" : "f";
            put(table, offset, 8);
            expected.tensors.push_back(t);
            ++count;
        }
    }
    for (int i = 0; i < 4; ++i)
        table[size_t(i)] = char(count >> (8 * i) & 0xff);
    std::string header;
    put(header, 0x41D7, 2);
    put(header, 2, 1);
    put(header, 0, 1);
    put(header, 16 + data.size(), 8);
    put(header, 0, 4);  // to 16 bytes: the data starts aligned
    std::ofstream(path, std::ios::binary) << header << data << table;
    return expected;
}

// A render with colour, albedo and normal of w x h pixels, HDR with a few bright pixels.
ImageBuf render(int w, int h, uint32_t seed)
{
    ImageSpec spec(w, h, 9, OIIO::TypeDesc::FLOAT);
    spec.channelnames = { "R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z" };
    ImageBuf buf(spec);
    std::mt19937 random(seed);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float p[9];
            for (int c = 0; c < 3; ++c)
                p[c] = u(random) * (u(random) < 0.01f ? 50.0f : 1.0f);
            for (int c = 3; c < 6; ++c)
                p[c] = u(random);
            for (int c = 6; c < 9; ++c)
                p[c] = 2.0f * u(random) - 1.0f;
            buf.setpixel(x, y, p);
        }
    return buf;
}

// The render with `names` added after its 9 channels, their values from fill(x, y, p): p holds
// the render's 9 values and room for the added ones after them.
ImageBuf with_channels(const ImageBuf& render, const std::vector<std::string>& names,
                       const std::function<void(int x, int y, float* p)>& fill)
{
    ImageSpec spec = render.spec();
    for (const std::string& name : names)
        spec.channelnames.push_back(name);
    spec.nchannels = int(spec.channelnames.size());
    ImageBuf buf(spec);
    std::vector<float> p(size_t(spec.nchannels));
    for (int y = 0; y < spec.height; ++y)
        for (int x = 0; x < spec.width; ++x) {
            render.getpixel(x, y, p.data(), 9);
            fill(x, y, p.data());
            buf.setpixel(x, y, p.data(), spec.nchannels);
        }
    return buf;
}

OidnOptions options_with(const std::string& weights)
{
    OidnOptions o;
    o.aovs.preset = "generic";
    o.aovs.overrides = { { "albedo", { "albedo.R", "albedo.G", "albedo.B" } },
                         { "normal", { "N.X", "N.Y", "N.Z" } } };
    o.weights = weights;
    o.skip.enabled = false;
    return o;
}

std::string temp_path(const std::string& name)
{
    return OIIO::Filesystem::temp_directory_path() + "/mcdn_oidn_" + std::to_string(getpid()) + "_"
           + name;
}

float max_abs_difference(const ImageBuf& a, const ImageBuf& b)
{
    auto stats = OIIO::ImageBufAlgo::compare(a, b, 0, 0);
    return float(stats.maxerror);
}

}  // namespace

TEST(Oidn, TensorArchiveReadAsWritten)
{
    const std::string path = temp_path("tiny.tza");
    const nn::Weights expected = write_tiny_tza(path, 9, 4, 1);
    nn::Weights read;
    std::string error;
    ASSERT_TRUE(oidn_net::read_tza(path, read, error)) << error;
    ASSERT_EQ(read.tensors.size(), expected.tensors.size());
    for (size_t i = 0; i < read.tensors.size(); ++i) {
        EXPECT_EQ(read.tensors[i].name, expected.tensors[i].name);
        EXPECT_EQ(read.tensors[i].shape, expected.tensors[i].shape);
        EXPECT_EQ(read.tensors[i].values, expected.tensors[i].values) << read.tensors[i].name;
    }
    // Cut short anywhere: an error naming the file, never a crash.
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    for (size_t cut : { size_t(3), size_t(15), bytes.size() / 2, bytes.size() - 9 }) {
        std::ofstream(path, std::ios::binary) << bytes.substr(0, cut);
        EXPECT_FALSE(oidn_net::read_tza(path, read, error)) << cut;
        EXPECT_NE(error.find(path), std::string::npos) << error;
    }
    std::remove(path.c_str());
}

TEST(Oidn, UnetOnTheEngineIsItsReferenceLoops)
{
    const std::string path = temp_path("unet.tza");
    write_tiny_tza(path, 9, 8, 2);
    nn::Weights weights;
    nn::Net fast, plain;
    std::string error;
    ASSERT_TRUE(oidn_net::read_tza(path, weights, error)) << error;
    ASSERT_TRUE(oidn_net::build_unet(fast, weights, error)) << error;
    ASSERT_TRUE(oidn_net::build_unet(plain, weights, error)) << error;
    EXPECT_EQ(fast.alignment(), 16);
    nn::Tensor input(48, 64, 9);
    std::mt19937 random(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (float& v : input.data)
        v = u(random);
    std::vector<nn::Tensor> a, b;
    ASSERT_TRUE(fast.run({ input }, a, error)) << error;
    ASSERT_TRUE(plain.run({ input }, b, error, nn::Backend::reference)) << error;
    ASSERT_EQ(a[0].data.size(), b[0].data.size());
    double worst = 0;
    for (size_t i = 0; i < a[0].data.size(); ++i)
        worst = std::max(worst, double(std::abs(a[0].data[i] - b[0].data[i])));
    EXPECT_LT(worst, 1e-4);
    std::remove(path.c_str());
}

TEST(Oidn, TransferFunctionRoundTrips)
{
    EXPECT_NEAR(oidn_net::pu_forward(65504.0f), 1.0f, 1e-6f);
    for (float y : { 0.0f, 1e-7f, 1e-4f, 0.01f, 0.18f, 1.0f, 30.0f, 1000.0f, 65504.0f })
        EXPECT_NEAR(oidn_net::pu_inverse(oidn_net::pu_forward(y)), y, 1e-4f * std::max(y, 1e-3f))
            << y;
}

TEST(Oidn, SameForAnyThreadsTilesAndBands)
{
    const std::string path = temp_path("same.tza");
    write_tiny_tza(path, 9, 8, 4);
    const ImageBuf src = render(83, 61, 5);
    OidnOptions o = options_with(path);
    ImageBuf one, two, small_tiles;
    ASSERT_TRUE(oidn(one, src, o, {}, 1)) << one.geterror();
    ASSERT_TRUE(oidn(two, src, o, {}, 2)) << two.geterror();
    EXPECT_EQ(max_abs_difference(one, two), 0.0f);
    o.tile_size = 16;
    ASSERT_TRUE(oidn(small_tiles, src, o, {}, 2)) << small_tiles.geterror();
    EXPECT_LT(max_abs_difference(one, small_tiles), 1e-5f);
    // In a chain cut into bands of rows, the frame's exposure travels with each band.
    ChainOptions chain;
    chain.aovs = o.aovs;
    chain.stages = { "oidn" };
    chain.settings = { { "oidn.weights", path }, { "oidn.skip", "0" } };
    chain.band_pixels = 83 * 16;
    chain.band_halos = 0;  // bands of 16 rows, as asked
    ImageBuf banded;
    ASSERT_TRUE(run_chain(banded, src, chain, {}, 2)) << banded.geterror();
    EXPECT_LT(max_abs_difference(one, banded), 1e-5f);
    // The input's own channels besides the colour are kept.
    EXPECT_EQ(one.nchannels(), 9);
    std::remove(path.c_str());
}

// prefilter=1: OIDN's networks for the albedo and the normal (rt_alb, rt_nrm, beside
// rt_hdr_calb_cnrm) clean the features first; the same for any threads, tiles and bands (whose
// halo doubles: the features reach as far again); without their files or the features, an
// error says which.
TEST(Oidn, PrefilteredFeaturesSameForAnyThreadsTilesAndBands)
{
    const std::string folder = temp_path("prefilter");
    ASSERT_TRUE(OIIO::Filesystem::create_directory(folder));
    // The same weights for both models: what differs is the prefilters' work.
    write_tiny_tza(folder + "/rt_hdr_alb_nrm.tza", 9, 8, 12);
    write_tiny_tza(folder + "/rt_hdr_calb_cnrm.tza", 9, 8, 12);
    write_tiny_tza(folder + "/rt_alb.tza", 3, 8, 13);
    write_tiny_tza(folder + "/rt_nrm.tza", 3, 8, 14);
    const ImageBuf src = render(64, 300, 15);
    OidnOptions o = options_with(folder);
    o.outliers = OidnOptions::Outliers::Off;
    ImageBuf plain, one, two, small_tiles;
    ASSERT_TRUE(oidn(plain, src, o, {}, 2)) << plain.geterror();
    const int plain_reach = receptive_radius(o);
    o.prefilter = true;
    EXPECT_EQ(receptive_radius(o), 2 * plain_reach);
    ASSERT_TRUE(oidn(one, src, o, {}, 1)) << one.geterror();
    ASSERT_TRUE(oidn(two, src, o, {}, 2)) << two.geterror();
    EXPECT_EQ(max_abs_difference(one, two), 0.0f);
    EXPECT_GT(max_abs_difference(one, plain), 1e-3f);
    o.tile_size = 16;
    ASSERT_TRUE(oidn(small_tiles, src, o, {}, 2)) << small_tiles.geterror();
    EXPECT_LT(max_abs_difference(one, small_tiles), 1e-5f);
    ChainOptions chain;
    chain.aovs = o.aovs;
    chain.stages = { "oidn" };
    chain.settings = { { "oidn.weights", folder },
                       { "oidn.skip", "0" },
                       { "oidn.outliers", "off" },
                       { "oidn.prefilter", "1" } };
    chain.band_pixels = 64 * 16;
    chain.band_halos = 0;  // bands of 16 rows
    ImageBuf banded;
    ASSERT_TRUE(run_chain(banded, src, chain, {}, 2)) << banded.geterror();
    EXPECT_LT(max_abs_difference(one, banded), 1e-5f);
    // Without a normal, or without a prefilter's file: one line saying which.
    OidnOptions no_normal = o;
    no_normal.aovs.overrides.erase("normal");
    const ImageBuf rgb_albedo = OIIO::ImageBufAlgo::channels(src, 6, {});
    ImageBuf out;
    EXPECT_FALSE(oidn(out, rgb_albedo, no_normal));
    EXPECT_NE(out.geterror().find("no normal"), std::string::npos) << out.geterror();
    std::remove((folder + "/rt_nrm.tza").c_str());
    ImageBuf missing;
    EXPECT_FALSE(oidn(missing, src, o));
    EXPECT_NE(missing.geterror().find(folder + "/rt_nrm.tza"), std::string::npos)
        << missing.geterror();
    for (const char* name : { "rt_hdr_alb_nrm", "rt_hdr_calb_cnrm", "rt_alb" })
        std::remove((folder + "/" + name + ".tza").c_str());
    std::remove(folder.c_str());
}

// --choose:with=cnn weighs our CNN beside OIDN by their SURE, as --denoise does with OIDN's
// weights and a variance. Streamed in bands of rows it gives the whole frame's result: the CNN
// that choose runs reads the frame's depth range, not the band's, and the bands' halos reach
// as far as choose's CNN does. Where the render is noisier than noise= over every window, the
// CNN is not run and the result is OIDN's with the mix.
TEST(Oidn, ChooseWithTheCnnSameInBandsAsWhole)
{
    const std::string path = temp_path("choose.tza");
    write_tiny_tza(path, 9, 8, 16);
    const int w = 24, h = 480;  // taller than the chain's reach (167 rows) and its halos
    const ImageBuf src =
        with_channels(render(w, h, 17), { "variance.R", "variance.G", "variance.B", "Z" },
                      [](int, int y, float* p) {
                          for (int c = 0; c < 3; ++c)
                              p[9 + c] = 0.05f * (p[c] * p[c] + 0.01f);
                          // each band's depth range is its own
                          p[12] = 1.0f + 0.1f * float(y);
                      });
    const AovSpec aovs = options_with(path).aovs;
    DenoisePlan plan;
    std::string error;
    ASSERT_TRUE(plan_denoise(plan, src.spec(), aovs, error, { { "oidn.weights", path } })) << error;
    EXPECT_EQ(plan.stages, (std::vector<std::string> { "oidn", "sure", "choose", "mix" }));
    EXPECT_EQ(plan.settings["choose.with"], "cnn");
    EXPECT_NE(plan.describe().find("choose (cnn)"), std::string::npos) << plan.describe();
    ASSERT_TRUE(plan_denoise(plan, src.spec(), aovs, error,
                             { { "oidn.weights", path }, { "denoise.choose", "0" } }));
    EXPECT_EQ(plan.stages, (std::vector<std::string> { "oidn", "sure", "mix" }));

    // Weighed everywhere (noise=0: this render's relative variance is 0.05).
    ChainOptions chain;
    chain.aovs = aovs;
    chain.stages = { "oidn", "sure", "choose", "mix" };
    chain.settings = { { "oidn.weights", path },
                       { "choose.with", "cnn" },
                       { "choose.noise", "0" } };
    ImageBuf whole, banded, without, gated;
    ASSERT_TRUE(run_chain(whole, src, chain, {}, 2)) << whole.geterror();
    EXPECT_GT(whole.spec().get_float_attribute(kChooseShareAttribute, 0), 0.01f);
    chain.band_pixels = w * 64;
    chain.band_halos = 0;  // bands of 64 rows
    ASSERT_TRUE(run_chain(banded, src, chain, {}, 2)) << banded.geterror();
    EXPECT_LT(max_abs_difference(whole, banded), 1e-5f);
    // The CNN's share changes the result; with the default noise=0.003 it weighs nowhere
    // here, and the result is the chain's without choose.
    chain.band_pixels = 0;
    chain.settings.erase("choose.noise");
    ASSERT_TRUE(run_chain(gated, src, chain, {}, 2)) << gated.geterror();
    EXPECT_EQ(gated.spec().get_float_attribute(kChooseShareAttribute, -1), 0.0f);
    chain.stages = { "oidn", "sure", "mix" };
    chain.settings.erase("choose.with");
    ASSERT_TRUE(run_chain(without, src, chain, {}, 2)) << without.geterror();
    EXPECT_GT(max_abs_difference(whole, without), 1e-3f);
    EXPECT_LT(max_abs_difference(gated, without), 1e-5f);
    // Not a denoiser choose knows: the setting's error says which it takes.
    chain.stages = { "oidn", "sure", "choose", "mix" };
    chain.settings["choose.with"] = "mix";
    ImageBuf refused;
    EXPECT_FALSE(run_chain(refused, src, chain, {}, 2));
    EXPECT_NE(refused.geterror().find("nfor, cnn or oidn"), std::string::npos)
        << refused.geterror();
    std::remove(path.c_str());
}

// The half files are read only for a stage that runs NFOR (mcdntool's input selection):
// --denoise with OIDN's weights runs our CNN beside OIDN, which read none; without them NFOR
// beside the CNN, as choose does by default. At 1080p reading them cost 0.6 GB of 2.5.
TEST(Oidn, HalvesReadOnlyWhereNforRuns)
{
    const std::string folder = mcdn_test::temp_dir("oidn_halves");
    write_tiny_tza(folder + "/rt_hdr_alb_nrm.tza", 9, 8, 3);
    const StageInfo& denoise = *find_stage("denoise");
    const StageInfo& choose = *find_stage("choose");
    EXPECT_TRUE(find_stage("nfor")->reads_halves({}));
    EXPECT_FALSE(find_stage("oidn")->reads_halves({}));
    EXPECT_FALSE(find_stage("cnn")->reads_halves({}));
    EXPECT_TRUE(choose.reads_halves({}));
    EXPECT_TRUE(choose.reads_halves({ { "with", "nfor" } }));
    EXPECT_FALSE(choose.reads_halves({ { "with", "cnn" } }));
    EXPECT_FALSE(choose.reads_halves({ { "with", "oidn" } }));
    setenv("MCDN_OIDN_WEIGHTS", "/nonexistent", 1);
    EXPECT_TRUE(denoise.reads_halves({}));
    setenv("MCDN_OIDN_WEIGHTS", folder.c_str(), 1);
    EXPECT_FALSE(denoise.reads_halves({}));
    EXPECT_FALSE(denoise.reads_halves({ { "choose", "0" } }));
    EXPECT_TRUE(denoise.reads_halves({ { "frames", "2" } }));  // the neighbours' agreement
    // And every role's variance only where our CNN runs: not for oidn, sure, mix (choose=0).
    EXPECT_TRUE(denoise.reads_all_variances({}));
    EXPECT_FALSE(denoise.reads_all_variances({ { "choose", "0" } }));
    EXPECT_TRUE(denoise.reads_all_variances({ { "choose", "0" }, { "frames", "2" } }));
    setenv("MCDN_OIDN_WEIGHTS", "/nonexistent", 1);
    EXPECT_TRUE(denoise.reads_all_variances({ { "choose", "0" } }));
    unsetenv("MCDN_OIDN_WEIGHTS");
    std::remove((folder + "/rt_hdr_alb_nrm.tza").c_str());
}

// --oidn reads the variance of the colour alone (its outlier rule), as sure and the mix do,
// none of the other roles' faces (mcdntool's input selection): the 8K band held 70 channels
// of Blender's four files where it needs 42. What -o writes is what reading every channel
// gives.
TEST(Oidn, ReadsNoVarianceButTheColours)
{
    for (const StageInfo& stage : stage_table())
        EXPECT_EQ(stage.reads_all_variances({}),
                  stage.name != "oidn" && stage.name != "sure" && stage.name != "mix")
            << stage.name;
    const std::string folder = mcdn_test::temp_dir("oidn_variances");
    const std::string path = folder + "/rt_hdr_alb_nrm.tza";
    write_tiny_tza(path, 9, 8, 17);
    const std::string stem = mcdn_test::test_data("box16/box_0016spp");
    const std::vector<InputFile> files = { { stem + ".exr", InputKind::Mean },
                                           { stem + "_var.exr", InputKind::Variance },
                                           { stem + "_A.exr", InputKind::HalfA },
                                           { stem + "_B.exr", InputKind::HalfB } };
    InputSelection selection;
    selection.only_roles = true;
    selection.light_split = false;
    selection.halves = false;
    selection.all_variances = false;
    ImageBuf all, some;
    ASSERT_TRUE(read_inputs(all, files)) << all.geterror();
    ASSERT_TRUE(read_inputs(some, files, selection)) << some.geterror();
    for (const char* name : { "variance.ViewLayer.Combined.R", "variance.ViewLayer.Combined.B",
                              "ViewLayer.DiffDir.R", "ViewLayer.Denoising Albedo.G" })
        EXPECT_GE(some.spec().channelindex(name), 0) << name;
    for (const char* name : { "variance.ViewLayer.DiffDir.R", "variance.ViewLayer.Emit.G",
                              "variance.ViewLayer.Denoising Albedo.R", "A.ViewLayer.Combined.R" }) {
        EXPECT_GE(all.spec().channelindex(name), 0) << name;
        EXPECT_LT(some.spec().channelindex(name), 0) << name;
    }
    for (std::vector<std::string> stages :
         { std::vector<std::string> { "oidn" }, { "oidn", "sure", "mix" } }) {
        ChainOptions o;
        o.stages = stages;
        o.settings = { { "oidn.weights", path } };
        o.band_pixels = 0;
        ImageBuf expected, result;
        ASSERT_TRUE(run_chain(expected, all, o, {}, 2)) << expected.geterror();
        o.output_channels_only = true;
        ASSERT_TRUE(run_chain(result, some, o, {}, 2)) << result.geterror();
        mcdn_test::expect_output_channels_equal(expected, result, all);
    }
    std::remove(path.c_str());
}

TEST(Oidn, ErrorsNameTheFileAndWhereWeightsComeFrom)
{
    const ImageBuf src = render(32, 32, 6);
    ImageBuf dst;
    OidnOptions o = options_with("/nonexistent/rt_hdr_alb_nrm.tza");
    EXPECT_FALSE(oidn(dst, src, o));
    const std::string message = dst.geterror();
    for (const char* part : { "/nonexistent/rt_hdr_alb_nrm.tza", "$MCDN_OIDN_WEIGHTS",
                              "share/mcdenoise/oidn", "RenderKit/oidn-weights" })
        EXPECT_NE(message.find(part), std::string::npos) << message;
    // A model reading an albedo on an input without one.
    const std::string path = temp_path("albedo.tza");
    write_tiny_tza(path, 6, 4, 7);
    OidnOptions color_only;
    color_only.aovs.preset = "generic";
    color_only.weights = path;
    ImageBuf rgb = OIIO::ImageBufAlgo::channels(src, 3, {}, {}, { "R", "G", "B" });
    ImageBuf out;
    EXPECT_FALSE(oidn(out, rgb, color_only));
    EXPECT_NE(out.geterror().find("an albedo"), std::string::npos) << out.geterror();
    std::remove(path.c_str());
}

// A heavy-tailed pixel enters the network as its neighbourhood (OidnOptions::outliers): the
// result changes only within the network's reach of it, and nowhere without a variance.
TEST(Oidn, HeavyTailedPixelsEnterAsTheirNeighbourhood)
{
    const std::string path = temp_path("outliers.tza");
    write_tiny_tza(path, 9, 8, 8);
    const int w = 96, h = 96;
    ImageBuf src = render(w, h, 9);
    ImageSpec spec = src.spec();
    // The render's variance: small everywhere but at one firefly, 40x its neighbours.
    ImageBuf with_variance = OIIO::ImageBufAlgo::channel_append(
        src, ImageBuf(ImageSpec(w, h, 3, OIIO::TypeDesc::FLOAT)));
    with_variance.specmod().channelnames = spec.channelnames;
    for (const char* c : { "variance.R", "variance.G", "variance.B" })
        with_variance.specmod().channelnames.push_back(c);
    const int fx = 50, fy = 40;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 3; ++c) {
                const bool firefly = x == fx && y == fy;
                float value[12];
                with_variance.getpixel(x, y, value, 12);
                value[c] = firefly ? 400.0f : 0.4f;
                value[9 + c] = firefly ? 1e4f : 1e-3f;
                with_variance.setpixel(x, y, value, 12);
            }
    OidnOptions o = options_with(path);
    o.aovs.overrides["color_variance"] = { "variance.R", "variance.G", "variance.B" };
    ImageBuf dropped, kept;
    ASSERT_TRUE(oidn(dropped, with_variance, o, {}, 2)) << dropped.geterror();
    o.outliers = OidnOptions::Outliers::Off;
    ASSERT_TRUE(oidn(kept, with_variance, o, {}, 2)) << kept.geterror();
    const int reach = receptive_radius(o) + 2;
    float differs_near = 0, differs_far = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float a[12], b[12];
            dropped.getpixel(x, y, a, 12);
            kept.getpixel(x, y, b, 12);
            const float d = std::abs(a[0] - b[0]);
            (std::max(std::abs(x - fx), std::abs(y - fy)) <= reach ? differs_near : differs_far) +=
                d;
        }
    EXPECT_GT(differs_near, 0.0f);
    EXPECT_EQ(differs_far, 0.0f);
    std::remove(path.c_str());
}

// Light groups are denoised too and still add up to the denoised beauty (to rounding);
// extras=0 keeps them as rendered.
TEST(Oidn, ExtrasStillSumToTheBeauty)
{
    const std::string path = temp_path("extras.tza");
    write_tiny_tza(path, 9, 8, 10);
    const int w = 70, h = 50;
    const ImageBuf src =
        with_channels(render(w, h, 11), { "key.R", "key.G", "key.B", "fill.R", "fill.G", "fill.B" },
                      [w](int x, int, float* p) {
                          for (int c = 0; c < 3; ++c) {
                              // the key's share of the beauty
                              p[9 + c] = p[c] * float(x) / float(w);
                              p[12 + c] = p[c] - p[9 + c];
                          }
                      });
    OidnOptions o = options_with(path);
    o.aovs.extras = { { "key", { "key.R", "key.G", "key.B" } },
                      { "fill", { "fill.R", "fill.G", "fill.B" } } };
    ImageBuf out, kept;
    ASSERT_TRUE(oidn(out, src, o, {}, 2)) << out.geterror();
    float worst = 0, moved = 0;
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float p[15], q[15];
            out.getpixel(x, y, p, 15);
            src.getpixel(x, y, q, 15);
            for (int c = 0; c < 3; ++c) {
                worst = std::max(worst,
                                 std::abs(p[9 + c] + p[12 + c] - p[c]) / (1.0f + std::abs(p[c])));
                moved = std::max(moved, std::abs(p[9 + c] - q[9 + c]));
            }
        }
    EXPECT_LT(worst, 1e-4f);
    EXPECT_GT(moved, 0.0f);
    o.denoise_extras = false;
    ASSERT_TRUE(oidn(kept, src, o, {}, 2)) << kept.geterror();
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float p[15], q[15];
            kept.getpixel(x, y, p, 15);
            src.getpixel(x, y, q, 15);
            for (int c = 9; c < 15; ++c)
                ASSERT_EQ(p[c], q[c]);
        }
    std::remove(path.c_str());
}

// ../peers/oidn/README.md's measurements: relMSE of rt_hdr_alb_nrm against the reference.
TEST(Oidn, PublishedWeightsReproduceThePublishedNumbers)
{
    if (!OIIO::Filesystem::exists(kPeers + "/rt_hdr_alb_nrm.tza"))
        GTEST_SKIP() << "no " << kPeers;
    const std::string data = MCDN_SHARED_DATA;
    struct Row {
        std::vector<InputFile> inputs;
        std::string reference;
        double relmse;
    };
    const std::vector<Row> rows = {
        { { { data + "/box/box_0016spp.exr", InputKind::Mean } },
          data + "/box/box_ref.exr",
          0.00562 },
        { { { data + "/box/box_0064spp.exr", InputKind::Mean } },
          data + "/box/box_ref.exr",
          0.00194 },
        { { { data + "/box/box_0256spp.exr", InputKind::Mean } },
          data + "/box/box_ref.exr",
          0.00118 },
        { { { data + "/tungsten/cornell20", InputKind::Mean } },
          data + "/tungsten/cornell20/ref.pfm",
          0.00055 },
        { { { data + "/tungsten/materialtest", InputKind::Mean } },
          data + "/tungsten/materialtest/ref.pfm",
          0.00235 },
    };
    for (const Row& row : rows) {
        ImageBuf src, out;
        ASSERT_TRUE(read_inputs(src, row.inputs)) << src.geterror();
        OidnOptions o;
        o.weights = kPeers;
        o.skip.enabled = false;
        ASSERT_TRUE(oidn(out, src, o, {}, 2)) << out.geterror();
        AovSet aovs;
        std::string error;
        ASSERT_TRUE(resolve_aovs(aovs, {}, out.spec(), error)) << error;
        const ImageBuf reference(row.reference);
        MetricsOptions mo;
        mo.image_channels = aovs.channels(Role::Color);
        Metrics m;
        ASSERT_TRUE(compute_metrics(m, out, reference, mo, error)) << error;
        EXPECT_NEAR(m.relmse, row.relmse, 0.02 * row.relmse) << row.reference;
    }
}
