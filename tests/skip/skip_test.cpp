// Skipping what a frame does not need (mcdn/skip.h): the converged-tile map, each stage on a
// frame whose left tiles are converged, skip=0, constant features.
#include <cmath>

#include <OpenImageIO/imagebufalgo.h>

#include "skip/constant_features.h"
#include "skip/converged_tiles.h"
#include "mcdn/chain.h"
#include "mcdn/cnn.h"
#include "mcdn/io.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/sure.h"

#include "fixtures.h"
#include "mcdn_test.h"

using namespace mcdn;
using OIIO::ImageBuf;

namespace {

constexpr int T = kConvergedTileSize;

Plane constant_plane(int w, int h, float v)
{
    return Plane(w, h, v);
}

ImageBuf read_examples_box()
{
    return mcdn_test::read_render(std::string(MCDN_SOURCE_DIR) + "/examples/box/box_0016spp");
}

/// The 128² box crop (16 spp) with its first `tiles` columns of tiles converged: colour and
/// both halves from the 4096-spp reference, variance of the mean 1e-4 × (ref² + 0.01)
/// (relative standard error 0.01).
ImageBuf half_converged_box(int tiles = 1)
{
    ImageBuf render = read_examples_box();
    ImageBuf ref(std::string(MCDN_SOURCE_DIR) + "/examples/box/box_ref.exr");
    ref.read(0, 0, true, OIIO::TypeDesc::FLOAT);
    const OIIO::ImageSpec& spec = render.spec();
    EXPECT_EQ(spec.format, OIIO::TypeDesc::FLOAT);  // pixeladdr below writes floats
    for (int c = 0; c < 3; ++c) {
        const std::string name = std::string("ViewLayer.Combined.") + "RGB"[c];
        const int ref_channel = ref.spec().channelindex(name);
        for (int y = 0; y < spec.height; ++y)
            for (int x = 0; x < tiles * T; ++x) {
                const float r = ref.getchannel(x, y, 0, ref_channel);
                float* px = static_cast<float*>(render.pixeladdr(x, y));
                px[spec.channelindex(name)] = r;
                px[spec.channelindex("A." + name)] = r;
                px[spec.channelindex("B." + name)] = r;
                px[spec.channelindex("variance." + name)] = 1e-4f * (r * r + 0.01f);
            }
    }
    return render;
}

AovSpec cycles()
{
    AovSpec spec;
    spec.preset = "cycles";
    return spec;
}

std::vector<int> color_channels(const ImageBuf& buf)
{
    std::vector<int> ch;
    for (const char* n : { "ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B" })
        ch.push_back(buf.spec().channelindex(n));
    return ch;
}

/// Largest |a − b| of the colour over columns [x0, x1).
float max_color_difference(const ImageBuf& a, const ImageBuf& b, int x0, int x1)
{
    float worst = 0;
    const std::vector<int> ca = color_channels(a), cb = color_channels(b);
    for (int y = 0; y < a.spec().height; ++y)
        for (int x = x0; x < x1; ++x)
            for (int c = 0; c < 3; ++c) {
                const float va = a.getchannel(x, y, 0, ca[c]), vb = b.getchannel(x, y, 0, cb[c]);
                worst = std::max(worst, std::isfinite(va) && std::isfinite(vb) ? std::fabs(va - vb)
                                                                               : INFINITY);
            }
    return worst;
}

/// relMSE of the colour over columns [x0, x1) against the reference.
double relmse_columns(const ImageBuf& out, const ImageBuf& ref, int x0, int x1)
{
    const std::vector<int> co = color_channels(out), cr = color_channels(ref);
    double sum = 0;
    size_t n = 0;
    for (int y = 0; y < out.spec().height; ++y)
        for (int x = x0; x < x1; ++x)
            for (int c = 0; c < 3; ++c) {
                const double r = ref.getchannel(x, y, 0, cr[c]);
                const double d = out.getchannel(x, y, 0, co[c]) - r;
                sum += d * d / (r * r + 0.01);
                ++n;
            }
    return sum / n;
}

ImageBuf box_reference()
{
    ImageBuf ref(std::string(MCDN_SOURCE_DIR) + "/examples/box/box_ref.exr");
    ref.read(0, 0, true, OIIO::TypeDesc::FLOAT);
    return ref;
}

}  // namespace

TEST(ConvergedTiles, EachPixelsNeighbourhoodInItsTileDecides)
{
    const int w = 70, h = 40;  // 3 × 2 tiles, partial ones at the right and bottom
    Plane mean[3], variance[3];
    for (int c = 0; c < 3; ++c) {
        mean[c] = constant_plane(w, h, 1.0f);
        variance[c] = constant_plane(w, h, 1e-6f);  // relative standard error ~1e-3
    }
    ConvergedTiles m = find_converged_tiles(mean, variance, 0.08f);
    EXPECT_TRUE(m.all());
    // One pixel and channel at rse 0.0995 (what a variance estimate from a few seeds gives
    // some pixels of a converged tile): its 3×3 mean is rse 0.033, the tile stays converged.
    variance[1](10, 10) = 0.01f;
    EXPECT_TRUE(find_converged_tiles(mean, variance, 0.08f).all());
    // A firefly (rse 0.3, over kOutlierFactor × 0.08) holds its tile back alone.
    variance[0](40, 35) = 0.09f;
    // A 3×3 patch at rse 0.0995: its centre's neighbourhood is over 0.08.
    for (int y = 4; y <= 6; ++y)
        for (int x = 66; x <= 68; ++x)
            variance[2](x, y) = 0.01f;
    m = find_converged_tiles(mean, variance, 0.08f);
    EXPECT_EQ(m.count(), 4);
    EXPECT_TRUE(m.tile(0, 0));
    EXPECT_FALSE(m.tile(1, 1));
    EXPECT_FALSE(m.tile(2, 0));
    // A noisy column (rse 0.15) just across a tile's edge holds back its own tile only.
    for (int y = 0; y < 32; ++y)
        variance[0](32, y) = 0.0225f;
    m = find_converged_tiles(mean, variance, 0.08f);
    EXPECT_TRUE(m.tile(0, 0));
    EXPECT_FALSE(m.tile(1, 0));
    variance[2](20, 5) = NAN;  // NaN never converged
    m = find_converged_tiles(mean, variance, 0.08f);
    EXPECT_FALSE(m.tile(0, 0));
    EXPECT_TRUE(m.tile(0, 1));
    EXPECT_TRUE(m.pixel(10, 35));
    EXPECT_FALSE(m.covers({ 30, 30, 34, 34 }));
    EXPECT_TRUE(m.covers({ 0, 32, 32, 40 }));
    // Dark pixels are relative to relMSE's floor: sd 0.005 on black is rse 0.05.
    for (int c = 0; c < 3; ++c) {
        mean[c] = constant_plane(w, h, 0.0f);
        variance[c] = constant_plane(w, h, 0.005f * 0.005f);
    }
    EXPECT_TRUE(find_converged_tiles(mean, variance, 0.08f).all());
    EXPECT_FALSE(find_converged_tiles(mean, variance, 0.04f).any());
    EXPECT_FALSE(find_converged_tiles(mean, variance, 0.0f).any());
}

TEST(ConvergedTiles, FrameScanEqualsThePlanes)
{
    // converged_tiles_of reads a float frame in memory in one pass over its pixels; it must
    // decide as the planes (read_plane: sanitized) do, NaN, negative and huge values included.
    const int w = 70, h = 66;
    ImageSpec spec(w, h, 8, OIIO::TypeDesc::FLOAT);
    spec.channelnames = { "R", "G", "B", "N.X", "variance.R", "variance.G", "variance.B", "Z" };
    ImageBuf frame(spec);
    uint32_t state = 7;
    auto next = [&] {
        state = state * 1664525u + 1013904223u;
        return (state >> 8) * (1.0f / 16777216.0f);
    };
    std::vector<float> px(8);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            for (int c = 0; c < 8; ++c)
                px[c] = c >= 4 && c < 7 ? 1e-6f * next() : next();
            frame.setpixel(x, y, px.data(), 8);
        }
    const float odd[] = { NAN, -1.0f, 1e30f, INFINITY, 0.02f };
    for (int i = 0; i < 5; ++i) {
        frame.getpixel(5 + 33 * (i % 3), 3 + 20 * i % h, px.data(), 8);
        px[4 + i % 3] = odd[i];  // a variance
        frame.setpixel(5 + 33 * (i % 3), 3 + 20 * i % h, px.data(), 8);
        frame.getpixel(40, 10 + 11 * i, px.data(), 8);
        px[i % 3] = odd[i];  // a mean
        frame.setpixel(40, 10 + 11 * i, px.data(), 8);
    }
    AovSpec spec_aovs;
    spec_aovs.preset = "generic";
    AovSet aovs;
    std::string error;
    ASSERT_TRUE(resolve_aovs(aovs, spec_aovs, frame.spec(), error)) << error;
    Plane mean[3], variance[3];
    for (int c = 0; c < 3; ++c) {
        mean[c] = read_plane(frame, aovs.channels(Role::Color)[c]);
        variance[c] = read_plane(frame, aovs.channels(Role::ColorVariance)[c], true);
    }
    const ConvergedTiles planes = find_converged_tiles(mean, variance, 0.08f);
    const ConvergedTiles scanned = converged_tiles_of(frame, aovs, SkipOptions());
    EXPECT_GT(planes.count(), 0);
    EXPECT_LT(planes.count(), planes.tiles_x * planes.tiles_y);
    EXPECT_EQ(scanned.converged, planes.converged);
    // A half frame is read through the planes (its own values).
    const ImageBuf half = frame.copy(OIIO::TypeDesc::HALF);
    for (int c = 0; c < 3; ++c) {
        mean[c] = read_plane(half, aovs.channels(Role::Color)[c]);
        variance[c] = read_plane(half, aovs.channels(Role::ColorVariance)[c], true);
    }
    EXPECT_EQ(converged_tiles_of(half, aovs, SkipOptions()).converged,
              find_converged_tiles(mean, variance, 0.08f).converged);
}

TEST(ConvergedTiles, RectanglesCoverExactlyTheUnconvergedPixels)
{
    ConvergedTiles m;
    m.width = 200;
    m.height = 100;
    m.tiles_x = 7;
    m.tiles_y = 4;
    m.converged.assign(28, 0);
    for (int ty = 0; ty < 4; ++ty)
        for (int tx = 0; tx < 3; ++tx)
            m.converged[ty * 7 + tx] = 1;
    m.converged[2 * 7 + 5] = 1;
    std::vector<int> covered(200 * 100, 0);
    for (const Rect& r : unconverged_rects(m, 64, 8)) {
        EXPECT_EQ(r.x0 % 8, 0);
        EXPECT_EQ(r.y0 % 8, 0);
        EXPECT_LE(r.width(), 64);
        EXPECT_LE(r.height(), 64);
        for (int y = r.y0; y < r.y1; ++y)
            for (int x = r.x0; x < r.x1; ++x)
                ++covered[y * 200 + x];
    }
    for (int y = 0; y < 100; ++y)
        for (int x = 0; x < 200; ++x)
            ASSERT_EQ(covered[y * 200 + x], m.pixel(x, y) ? 0 : 1) << x << "," << y;
    ConvergedTiles decoded;
    ASSERT_TRUE(decode_converged_tiles(decoded, encode_converged_tiles(m), 200, 100));
    EXPECT_EQ(decoded.converged, m.converged);
    EXPECT_FALSE(decode_converged_tiles(decoded, encode_converged_tiles(m), 201, 100));
}

// The threshold against real renders: a 256-spp tile is never converged; a render 16 times
// the 4096-spp reference's samples (its variance / 16) always is, and the reference itself
// is at :converged=0.08.
TEST(ConvergedTilesShared, ThresholdSeparates256sppFromReferenceQuality)
{
    MCDN_REQUIRE_SHARED(box, "box");
    auto map_of = [&](const std::string& mean_file, const std::string& var_file, float var_scale,
                      float threshold = SkipOptions().max_relative_error) {
        ImageBuf mean(box + "/" + mean_file), var(box + "/" + var_file);
        Plane m[3], v[3];
        for (int c = 0; c < 3; ++c) {
            const std::string name = std::string("ViewLayer.Combined.") + "RGB"[c];
            m[c] = read_plane(mean, mean.spec().channelindex(name));
            v[c] = read_plane(var, var.spec().channelindex(name), true);
            for (float& x : v[c].px)
                x *= var_scale;
        }
        return find_converged_tiles(m, v, threshold);
    };
    EXPECT_EQ(map_of("box_0256spp.exr", "box_0256spp_var.exr", 1.0f).count(), 0);
    EXPECT_EQ(map_of("box_0256spp.exr", "box_0256spp_var.exr", 1.0f, 0.08f).count(), 0);
    EXPECT_TRUE(map_of("box_ref.exr", "box_ref_var.exr", 1.0f / 16).all());
    EXPECT_TRUE(map_of("box_ref.exr", "box_ref_var.exr", 1.0f, 0.08f).all());
}

TEST(SkipNfor, ConvergedTilesPassThroughAndTheRestIsUnchangedAwayFromThem)
{
    const ImageBuf src = half_converged_box();
    NforOptions on, off;
    on.aovs = off.aovs = cycles();
    off.skip.enabled = false;
    ImageBuf skipped = nfor(src, on, {}, 2), full = nfor(src, off, {}, 2);
    ASSERT_FALSE(skipped.has_error()) << skipped.geterror();
    ASSERT_FALSE(full.has_error()) << full.geterror();
    // The converged column of tiles is the render, bit for bit.
    EXPECT_EQ(max_color_difference(skipped, src, 0, T), 0.0f);
    EXPECT_GT(max_color_difference(full, src, 0, T), 0.0f);  // the switch does something
    // Beyond the reach of NFOR's passes (~72 px: prefilter 13, first pass 18, maps 20,
    // second pass 21) the result is bit-identical; nearer, within the denoiser's own error.
    EXPECT_EQ(max_color_difference(skipped, full, T + 72, 128), 0.0f);
    const ImageBuf ref = box_reference();
    const double near_skipped = relmse_columns(skipped, ref, T, T + 72);
    const double near_full = relmse_columns(full, ref, T, T + 72);
    EXPECT_LT(near_skipped, 1.1 * near_full) << near_skipped << " vs " << near_full;
    // Identical for 1 and 2 threads, finite.
    ImageBuf one = nfor(src, on, {}, 1);
    EXPECT_EQ(max_color_difference(one, skipped, 0, 128), 0.0f);
}

TEST(SkipNfor, NothingConvergedIsTheUnskippedFilter)
{
    const ImageBuf src = read_examples_box();
    NforOptions on, off;
    on.aovs = off.aovs = cycles();
    off.skip.enabled = false;
    ImageBuf a = nfor(src, on, {}, 2), b = nfor(src, off, {}, 2);
    EXPECT_EQ(max_color_difference(a, b, 0, 128), 0.0f);
}

TEST(SkipNfor, ConstantFeatureIsDroppedNotFitted)
{
    ImageBuf src = read_examples_box();
    // A flat albedo (a grey card): constant in the mean and both halves.
    for (const std::string prefix : { "", "A.", "B." })
        for (const char* ch : { "R", "G", "B" }) {
            const int c = src.spec().channelindex(prefix + "ViewLayer.Denoising Albedo." + ch);
            ASSERT_GE(c, 0);
            OIIO::ImageBufAlgo::fill(src, { 0.5f }, OIIO::ROI(0, 128, 0, 128, 0, 1, c, c + 1));
        }
    FeaturePlanes flat { Plane(4, 4, 0.5f), Plane(4, 4, 0.0f), Plane(4, 4, 0.5f),
                         Plane(4, 4, 0.5f) };
    FeaturePlanes ramp = flat;
    ramp.half_b(3, 3) = 0.25f;
    std::vector<FeaturePlanes> features { flat, ramp, flat };
    EXPECT_EQ(drop_constant_features(features), 2);
    EXPECT_EQ(features.size(), 1u);

    NforOptions on, off;
    on.aovs = off.aovs = cycles();
    off.skip.enabled = false;
    ImageBuf dropped = nfor(src, on, {}, 2), fitted = nfor(src, off, {}, 2);
    ASSERT_FALSE(dropped.has_error()) << dropped.geterror();
    // The zero column changes only float rounding of the solve.
    const ImageBuf ref = box_reference();
    const double e_dropped = relmse_columns(dropped, ref, 0, 128);
    const double e_fitted = relmse_columns(fitted, ref, 0, 128);
    EXPECT_NEAR(e_dropped, e_fitted, 0.02 * e_fitted);
    EXPECT_LT(max_color_difference(dropped, fitted, 0, 128), 1e-2f);

    // The prefilter leaves the constant channels untouched, variance included.
    PrefilterOptions p;
    p.aovs = cycles();
    ImageBuf filtered = prefilter(src, p, {}, 2);
    const int albedo_var = src.spec().channelindex("variance.ViewLayer.Denoising Albedo.R");
    ASSERT_GE(albedo_var, 0);
    for (int y = 0; y < 128; y += 7)
        for (int x = 0; x < 128; x += 7)
            ASSERT_EQ(filtered.getchannel(x, y, 0, albedo_var),
                      src.getchannel(x, y, 0, albedo_var));
}

TEST(SkipPrefilter, ConvergedTilesKeepTheirHalves)
{
    const ImageBuf src = half_converged_box();
    PrefilterOptions on;
    on.aovs = cycles();
    ImageBuf out = prefilter(src, on, {}, 2);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    const int normal_a = src.spec().channelindex("A.ViewLayer.Denoising Normal.X");
    float converged_change = 0, noisy_change = 0;
    for (int y = 0; y < 128; ++y)
        for (int x = 0; x < 128; ++x) {
            float d =
                std::fabs(out.getchannel(x, y, 0, normal_a) - src.getchannel(x, y, 0, normal_a));
            (x < T ? converged_change : noisy_change) =
                std::max(x < T ? converged_change : noisy_change, d);
        }
    EXPECT_EQ(converged_change, 0.0f);
    EXPECT_GT(noisy_change, 0.0f);
}

TEST(SkipCnn, ConvergedTilesPassThroughAndFarPixelsAreUnchanged)
{
    const ImageBuf src = half_converged_box(3);  // the network runs on x >= 96 only
    CnnOptions on, off;
    on.aovs = off.aovs = cycles();
    off.skip.enabled = false;
    ImageBuf skipped = cnn(src, on, {}, 2), full = cnn(src, off, {}, 2);
    ASSERT_FALSE(skipped.has_error()) << skipped.geterror();
    ASSERT_FALSE(full.has_error()) << full.geterror();
    EXPECT_EQ(max_color_difference(skipped, src, 0, 3 * T), 0.0f);
    EXPECT_GT(max_color_difference(full, src, 0, 3 * T), 0.0f);
    // Every output pixel of a tiled run sees what a whole-image run sees (nn::run_tiled),
    // so the noisy half is the unskipped result up to the float rounding of other blockings.
    EXPECT_LT(max_color_difference(skipped, full, 3 * T, 128), 1e-4f);
    ImageBuf one = cnn(src, on, {}, 1);
    EXPECT_EQ(max_color_difference(one, skipped, 0, 128), 0.0f);
}

TEST(SkipCnn, ConvergedTilesPassThroughWhenTheWholeFrameRuns)
{
    // One converged tile column: the network's reach covers the whole frame from the
    // noisy tiles, so it runs on every tile; the converged ones still keep the render.
    const ImageBuf src = half_converged_box(1);
    CnnOptions on;
    on.aovs = cycles();
    ImageBuf out = cnn(src, on, {}, 2);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    EXPECT_EQ(max_color_difference(out, src, 0, T), 0.0f);
    EXPECT_GT(max_color_difference(out, src, T, 128), 0.0f);
}

TEST(SkipSureMix, ConvergedTilesAreTheRenderWithTheirExactError)
{
    const ImageBuf src = half_converged_box();
    NforOptions n;
    n.aovs = cycles();
    Denoiser denoiser = [&](ImageBuf& dst, const ImageBuf& in) { return nfor(dst, in, n, {}, 2); };
    SureOptions s;
    s.aovs = cycles();
    ImageBuf with_error = sure(src, denoiser, s, {}, 2);
    ASSERT_FALSE(with_error.has_error()) << with_error.geterror();
    EXPECT_TRUE(with_error.spec().get_string_attribute(kConvergedAttribute).empty());
    const int div = with_error.spec().channelindex("sure.divergence.G");
    const int est = with_error.spec().channelindex("sure.G");
    const int var = src.spec().channelindex("variance.ViewLayer.Combined.G");
    for (int y = 0; y < 128; y += 5)
        for (int x = 0; x < T; x += 3) {
            ASSERT_EQ(with_error.getchannel(x, y, 0, div), src.getchannel(x, y, 0, var));
            ASSERT_EQ(with_error.getchannel(x, y, 0, est), src.getchannel(x, y, 0, var));
        }
    for (MixOptions::Model model : { MixOptions::Model::Analytic, MixOptions::Model::Net }) {
        MixOptions m;
        m.aovs = cycles();
        m.model = model;
        m.output_alpha = true;
        ImageBuf mixed = mix(with_error, m, {}, 2);
        ASSERT_FALSE(mixed.has_error()) << mixed.geterror();
        EXPECT_EQ(max_color_difference(mixed, src, 0, T), 0.0f);
        const int alpha = mixed.spec().channelindex("mix.alpha.R");
        float alpha_max = 0;
        for (int y = 0; y < 128; ++y)
            for (int x = 0; x < T; ++x)
                alpha_max = std::max(alpha_max, mixed.getchannel(x, y, 0, alpha));
        EXPECT_EQ(alpha_max, 0.0f);
        // Away from the converged tiles the mix is the unskipped one.
        m.skip.enabled = false;
        ImageBuf full = mix(with_error, m, {}, 2);
        EXPECT_EQ(max_color_difference(mixed, full, T + 16, 128), 0.0f);
        EXPECT_LT(max_color_difference(mixed, full, 0, 128), INFINITY);  // finite
    }
}

// A frame converged everywhere (every tile of reference quality): every chain gives the
// render back, bit for bit, and the mix runs neither model nor t-test on it.
TEST(SkipChains, AConvergedFrameIsTheRenderThroughEveryChain)
{
    const ImageBuf src = half_converged_box(4);  // 128²: all four tile columns
    AovSet aovs;
    std::string error;
    ASSERT_TRUE(resolve_aovs(aovs, cycles(), src.spec(), error)) << error;
    const ConvergedCount count = count_converged_tiles(src, aovs);
    EXPECT_EQ(count.converged, 16);
    EXPECT_EQ(count.tiles, 16);
    for (const std::vector<std::string>& stages :
         { std::vector<std::string> { "cnn", "sure", "mix" },
           { "prefilter", "nfor", "sure", "mix" },
           { "denoise" } }) {
        ChainOptions chain;
        chain.aovs = cycles();
        chain.stages = stages;
        chain.settings["mix.alpha"] = "1";
        ImageBuf out;
        ASSERT_TRUE(run_chain(out, src, chain, {}, 2)) << out.geterror();
        EXPECT_EQ(max_color_difference(out, src, 0, 128), 0.0f) << stages[0];
        const int alpha = out.spec().channelindex("mix.alpha.G");
        if (alpha >= 0) {
            for (int y = 0; y < 128; y += 7)
                for (int x = 0; x < 128; x += 7)
                    ASSERT_EQ(out.getchannel(x, y, 0, alpha), 0.0f);
        }
    }
}

TEST(SkipFrontEnds, RecipeKeyAndCommandLineModifier)
{
    const ImageBuf src = half_converged_box();
    ChainOptions chain;
    chain.aovs = cycles();
    chain.stages = { "nfor" };
    chain.settings["nfor.skip"] = "0";
    ImageBuf from_recipe;
    ASSERT_TRUE(run_chain(from_recipe, src, chain, {}, 2)) << from_recipe.geterror();
    EXPECT_GT(max_color_difference(from_recipe, src, 0, T), 0.0f);  // filtered: skip off
    chain.settings.clear();                                         // default: skipping on
    ImageBuf skipped;
    ASSERT_TRUE(run_chain(skipped, src, chain, {}, 2)) << skipped.geterror();
    EXPECT_EQ(max_color_difference(skipped, src, 0, T), 0.0f);

    const std::string b = mcdn_test::test_data("box16/box_0016spp");
    const std::string inputs = mcdn_test::quote(b + ".exr") + " -i:as=variance "
                               + mcdn_test::quote(b + "_var.exr") + " -i:as=halfA "
                               + mcdn_test::quote(b + "_A.exr") + " -i:as=halfB "
                               + mcdn_test::quote(b + "_B.exr");
    const std::string out = mcdn_test::temp_dir("skip_cli") + "/out.exr";
    auto bad =
        mcdn_test::run_mcdntool("-i " + inputs + " --nfor:skip=2 -o " + mcdn_test::quote(out));
    EXPECT_NE(bad.exit_code, 0);
    EXPECT_NE(bad.output.find("--nfor:skip=2 must be 0 or 1"), std::string::npos) << bad.output;
    auto negative = mcdn_test::run_mcdntool("-i " + inputs + " --sure:converged=-1 -o "
                                            + mcdn_test::quote(out));
    EXPECT_NE(negative.exit_code, 0);
    auto good = mcdn_test::run_mcdntool("-i " + inputs + " --nfor:skip=0:converged=0.05 -o "
                                        + mcdn_test::quote(out));
    EXPECT_EQ(good.exit_code, 0) << good.output;
}
