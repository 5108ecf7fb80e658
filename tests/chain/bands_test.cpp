// A chain run in bands (ChainOptions::band_pixels) gives the whole frame's result: the frame's
// statistics, probes and tile grids are the whole frame's in every band.
#include <gtest/gtest.h>

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/chain.h"
#include "mcdn/denoise.h"

#include "fixtures.h"

using namespace mcdn;
using OIIO::ImageBuf;

namespace {

// box16 stacked eight times (64x512): bands of 64 rows whose halos (the chain's reach, up to
// 128 rows) still cut the frame in several places.
const ImageBuf& taller_box16()
{
    static const ImageBuf tall = [] {
        ImageBuf one = mcdn_test::box16();
        OIIO::ImageSpec spec = one.spec();
        spec.height = spec.full_height = 8 * one.spec().height;
        ImageBuf out(spec);
        for (int i = 0; i < 8; ++i)
            EXPECT_TRUE(OIIO::ImageBufAlgo::paste(out, 0, i * one.spec().height, 0, 0, one));
        return out;
    }();
    return tall;
}

struct Case {
    std::vector<std::string> stages;
    std::map<std::string, std::string> settings;
    double tolerance;  // 0 but for the mixing network (its tiles fall differently)
};

void expect_bands_match(const Case& k)
{
    const ImageBuf& src = taller_box16();
    ChainOptions o;
    o.stages = k.stages;
    o.settings = k.settings;
    const std::string name = OIIO::Strutil::join(k.stages, ",");
    ImageBuf whole, banded;
    o.band_pixels = 0;
    ASSERT_TRUE(run_chain(whole, src, o)) << name << ": " << whole.geterror();
    o.band_pixels = 64 * 64;
    o.band_halos = 0;
    ASSERT_GT(chain_reach(src.spec(), o), 0) << name;
    ASSERT_TRUE(run_chain(banded, src, o)) << name << ": " << banded.geterror();
    ASSERT_EQ(whole.spec().channelnames, banded.spec().channelnames) << name;
    EXPECT_EQ(whole.spec().get_string_attribute("mcdn:denoise_plan"),
              banded.spec().get_string_attribute("mcdn:denoise_plan"));
    EXPECT_FALSE(banded.spec().find_attribute("mcdn:frame")) << name;
    // choose's share is the frame's mean over the bands' pixels (their halos too).
    if (whole.spec().find_attribute("mcdn:choose_share"))
        EXPECT_NEAR(banded.spec().get_float_attribute("mcdn:choose_share", -1),
                    whole.spec().get_float_attribute("mcdn:choose_share"), 0.02)
            << name;
    const auto cmp = OIIO::ImageBufAlgo::compare(whole, banded, 0, 0);
    EXPECT_LE(cmp.maxerror, k.tolerance)
        << name << " at " << cmp.maxx << "," << cmp.maxy << " channel " << cmp.maxc;
}

}  // namespace

TEST(Bands, CnnChainsAreTheWholeFrame)
{
    expect_bands_match({ { "cnn" }, {}, 0.0 });
    expect_bands_match({ { "cnn", "sure", "mix" }, { { "mix.model", "analytic" } }, 0.0 });
    expect_bands_match({ { "denoise" }, {}, 1e-4 });
}

TEST(Bands, NforChainsAreTheWholeFrame)
{
    expect_bands_match({ { "prefilter", "nfor" }, {}, 0.0 });
    expect_bands_match({ { "nfor" }, { { "nfor.halves", "0" } }, 0.0 });
    expect_bands_match(
        { { "prefilter", "nfor", "sure", "mix" }, { { "mix.model", "analytic" } }, 0.0 });
}

// A frame made in bands says what its bands' safety nets did: their tile counts summed,
// choose's share the mean over their pixels, each erased where no band had it.
TEST(Bands, TheSafetyNetsCountsAreTheBandsSums)
{
    auto band = [](int height, int nfor, int sure, float share) {
        OIIO::ImageSpec spec(8, height, 3, OIIO::TypeDesc::FLOAT);
        if (nfor >= 0)
            spec.attribute("mcdn:nfor_fallback_count", nfor);
        if (sure >= 0)
            spec.attribute("mcdn:sure_worse_count", sure);
        if (share >= 0)
            spec.attribute("mcdn:choose_share", share);
        return spec;
    };
    BandCounts counts;
    counts.add(band(10, 2, -1, 0.5f));
    counts.add(band(30, 3, 4, 0.1f));
    counts.add(band(20, -1, -1, -1));
    OIIO::ImageSpec frame = band(60, 2, -1, 0.5f);  // the first band's, as gathered
    frame.attribute("mcdn:sure_fallback_count", 7);
    counts.set(frame);
    EXPECT_EQ(frame.get_int_attribute("mcdn:nfor_fallback_count"), 5);
    EXPECT_EQ(frame.get_int_attribute("mcdn:sure_worse_count"), 4);
    EXPECT_FALSE(frame.find_attribute("mcdn:sure_fallback_count"));
    EXPECT_NEAR(frame.get_float_attribute("mcdn:choose_share"), (10 * 0.5 + 30 * 0.1) / 40, 1e-6);
}

TEST(Bands, ReachIsTheSumOfTheStages)
{
    ChainOptions o;
    o.stages = { "cnn" };
    const int cnn = chain_reach(taller_box16().spec(), o);
    o.stages = { "cnn", "sure", "mix" };
    const int mixed = chain_reach(taller_box16().spec(), o);
    o.stages = { "prefilter", "nfor" };
    const int nfor = chain_reach(taller_box16().spec(), o);
    // box16 has half buffers: --denoise chooses between the CNN and NFOR (mcdn/choose.h).
    o.stages = { "cnn", "sure", "choose", "mix" };
    const int best = chain_reach(taller_box16().spec(), o);
    o.stages = { "denoise" };
    EXPECT_EQ(chain_reach(taller_box16().spec(), o), best);
    EXPECT_GT(cnn, 10);
    EXPECT_GT(mixed, cnn);          // the mix reaches further still
    EXPECT_GT(best, mixed + nfor);  // choose runs NFOR on the render, then sums windows
}
