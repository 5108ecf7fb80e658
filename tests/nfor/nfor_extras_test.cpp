// Extra AOVs (light groups) denoised with the beauty's regression weights add up to the
// denoised beauty, with or without half buffers of their own, and are denoised, not copied.
#include <algorithm>

#include <OpenImageIO/imagebufalgo.h>

#include "fixtures.h"
#include "core/extra_aovs.h"
#include "mcdn/chain.h"
#include "mcdn/metrics.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/sure.h"
#include "partition.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

/// relMSE of channels `a` of x against channels `b` of y.
double channel_relmse(const OIIO::ImageBuf& x, const std::vector<int>& a, const OIIO::ImageBuf& y,
                      const std::vector<int>& b)
{
    MetricsOptions options;
    options.image_channels = a;
    options.reference_channels = b;
    Metrics m;
    std::string error;
    EXPECT_TRUE(compute_metrics(m, x, y, options, error)) << error;
    return m.relmse;
}

}  // namespace

TEST(NforExtras, LightGroupsAddUpToTheDenoisedBeauty)
{
    for (bool own_halves : { true, false }) {
        Partition p = add_light_groups(box16(), "cycles", own_halves);
        NforOptions o;
        o.aovs = p.spec;
        ImageBuf out = nfor(p.image, o);
        ASSERT_FALSE(out.has_error()) << out.geterror();
        EXPECT_LT(partition_error(out, p), 1e-4) << (own_halves ? "own halves" : "borrowed halves");
        EXPECT_LT(partition_error(p.image, p), 1e-5);  // the input partitions the beauty

        // Denoised, not copied: the key moved as far as the beauty's noise.
        const double changed = channel_relmse(out, p.key, p.image, p.key);
        EXPECT_GT(changed, 1e-3);
    }
}

// The rounding share (nfor/extras_regression.h) does not hide a wrong filter: with the fill shifted
// by a constant the input no longer adds up, nothing is shared, and the result is off by that
// constant (regressions reproduce constants) plus only the regressions' rounding.
TEST(NforExtras, WithoutTheRoundingShareTheyAddUpToRounding)
{
    Partition p = add_light_groups(box16(), "cycles", true);
    const float shift = 0.01f;
    std::vector<float> add(p.image.nchannels(), 0.0f);
    for (const char* face : { "", "A.", "B." })
        for (const char* c : { "R", "G", "B" }) {
            int ch =
                p.image.spec().channelindex(std::string(face) + "ViewLayer.Combined_fill." + c);
            ASSERT_GE(ch, 0);
            add[ch] = shift;
        }
    ImageBuf shifted = OIIO::ImageBufAlgo::add(p.image, add);
    NforOptions o;
    o.aovs = p.spec;
    ImageBuf out = nfor(shifted, o);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    EXPECT_LT(partition_error(out, p, shift), 1e-2);  // measured 3.7e-3 (2.5e-6 when shared)
    EXPECT_GT(partition_error(out, p, shift), 1e-5);  // and the share is really off here
}

TEST(NforExtras, SwitchedOffTheExtrasAreKept)
{
    Partition p = add_light_groups(box16(), "cycles", true);
    NforOptions o;
    o.aovs = p.spec;
    o.denoise_extras = false;
    ImageBuf out = nfor(p.image, o);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    EXPECT_EQ(channel_relmse(out, p.key, p.image, p.key), 0.0);
}

TEST(NforExtras, AnExtraThatIsNotRgbIsAnError)
{
    ImageBuf merged = box16();
    NforOptions o;
    std::string error;
    ASSERT_TRUE(o.aovs.parse_override("extra.depth=ViewLayer.Depth.Z", error)) << error;
    ImageBuf out = nfor(merged, o);
    ASSERT_TRUE(out.has_error());
    EXPECT_NE(out.geterror().find("extra aov 'depth'"), std::string::npos) << out.geterror();
}

// Through the progressive mix the extras get the beauty's alpha': they still add up.
TEST(NforExtras, ThroughSureAndMixTheyStillAddUp)
{
    Partition p = add_light_groups(box16(), "cycles", true);
    NforOptions n;
    n.aovs = p.spec;
    SureOptions s;
    s.aovs = p.spec;
    ImageBuf sured = sure(
        p.image, [&](ImageBuf& dst, const ImageBuf& src) { return nfor(dst, src, n); }, s);
    ASSERT_FALSE(sured.has_error()) << sured.geterror();
    MixOptions m;
    m.aovs = p.spec;
    ImageBuf out = mix(sured, m);
    ASSERT_FALSE(out.has_error()) << out.geterror();
    EXPECT_LT(partition_error(out, p), 1e-4);
    EXPECT_GT(channel_relmse(out, p.key, sured, p.key), 1e-6);  // mixed, not the NFOR result
}

// An empty light group (0 in its mean, halves and variance over the frame) is left out of the
// filters (read_extras does not hand it to them; one non-zero pixel and it is filtered): it
// stays 0 through nfor and cnn, run whole or in a chain's bands, and the other groups still
// add up to the denoised beauty.
TEST(NforExtras, AnEmptyLightGroupIsLeftAsRendered)
{
    Partition p = add_light_groups(box16(), "cycles", true);
    std::vector<std::string> names;
    for (const char* face : { "", "A.", "B.", "variance." })
        for (const char* c : { "R", "G", "B" })
            names.push_back(std::string(face) + "ViewLayer.Combined_empty." + c);
    OIIO::ImageSpec zero_spec(p.image.spec().width, p.image.spec().height, int(names.size()),
                              OIIO::TypeDesc::FLOAT);
    zero_spec.channelnames = names;
    ImageBuf zeros(zero_spec);
    OIIO::ImageBufAlgo::zero(zeros);
    ImageBuf with_empty = OIIO::ImageBufAlgo::channel_append(p.image, zeros);
    ASSERT_FALSE(with_empty.has_error()) << with_empty.geterror();
    std::vector<int> empty;
    for (int c = 0; c < 3; ++c)
        empty.push_back(with_empty.spec().channelindex(names[c]));
    AovSet aovs;
    std::string error;
    ASSERT_TRUE(resolve_aovs(aovs, p.spec, with_empty.spec(), error)) << error;
    // The light groups (box16's light passes are extras too: DiffDir, ..., Emit and Env,
    // which are 0 over the frame).
    auto groups = [](const auto& list) {
        return std::count_if(list.begin(), list.end(),
                             [](const auto& e) { return e.partition == "light groups"; });
    };
    ASSERT_EQ(groups(aovs.extras()), 3);
    std::vector<ExtraPlanes> extras;
    ASSERT_TRUE(read_extras(extras, with_empty, aovs, true, error)) << error;
    EXPECT_EQ(groups(extras), 2);  // key and fill
    ImageBuf lit;
    lit.copy(with_empty);
    std::vector<float> pixel(lit.nchannels());
    lit.getpixel(5, 7, pixel.data());
    pixel[empty[1]] = 0.5f;
    lit.setpixel(5, 7, pixel.data());
    ASSERT_TRUE(read_extras(extras, lit, aovs, true, error)) << error;
    EXPECT_EQ(groups(extras), 3);
    for (const std::vector<std::string>& stages :
         { std::vector<std::string> { "nfor" }, { "cnn" }, { "prefilter", "nfor", "sure", "mix" } })
        for (size_t band_pixels : { size_t(0), size_t(128 * 32) }) {
            ChainOptions chain;
            chain.aovs = p.spec;
            chain.stages = stages;
            chain.band_pixels = band_pixels;
            chain.band_halos = 0;
            ImageBuf out;
            ASSERT_TRUE(run_chain(out, with_empty, chain, {}, 2)) << out.geterror();
            float largest = 0;
            for (int y = 0; y < out.spec().height; ++y)
                for (int x = 0; x < out.spec().width; ++x)
                    for (int ch : empty)
                        largest = std::max(largest, std::fabs(out.getchannel(x, y, 0, ch)));
            EXPECT_EQ(largest, 0.0f) << stages[0] << ", bands of " << band_pixels;
            if (stages[0] != "cnn") {
                EXPECT_LT(partition_error(out, p), 1e-4) << stages[0];
            }
        }
}
