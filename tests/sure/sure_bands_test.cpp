// SURE of a large frame runs in bands (SureOptions::denoiser_radius, band_pixels): the
// result must be the whole-frame run's, bit for bit, which holds only when the probe step
// and the probes' random numbers are the frame's, not the band's, and each band's halo covers
// the denoiser's reach.
#include "mcdn/sure.h"

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/cnn.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/settings.h"
#include "fixtures.h"
#include "same_pixels.h"
#include "synthetic.h"
#include "sure/sure_steps.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

float ramp(int x, int y, int c)
{
    return 0.2f + 0.003f * x + 0.004f * (y % 50) + 0.1f * c;
}

ImageBuf sure_of(const ImageBuf& src, const Denoiser& denoiser, SureOptions options)
{
    ImageBuf out;
    EXPECT_TRUE(sure(out, src, denoiser, options, {}, 2)) << out.geterror();
    return out;
}

}  // namespace

TEST(SureBands, NforChainInBandsEqualsTheWholeFrame)
{
    // box16 stacked to 64x256, with a block of converged tiles (variance 0) across a band
    // edge, so the bands also skip exactly what the whole frame skips.
    ImageBuf src = tall_box16();
    for (const char* name : { "variance.ViewLayer.Combined.R", "variance.ViewLayer.Combined.G",
                              "variance.ViewLayer.Combined.B" }) {
        int c = src.spec().channelindex(name);
        ASSERT_GE(c, 0) << name;
        ASSERT_TRUE(OIIO::ImageBufAlgo::fill(src, { 0.0f }, ROI(0, 32, 96, 160, 0, 1, c, c + 1)));
    }
    PrefilterOptions p;
    NforOptions n;
    Denoiser chain = compose(
        { { "prefilter",
            [&](ImageBuf& d, const ImageBuf& s) { return prefilter(d, s, p, {}, 2); } },
          { "nfor", [&](ImageBuf& d, const ImageBuf& s) { return nfor(d, s, n, {}, 2); } } });
    SureOptions whole;
    whole.denoiser_radius = chain_radius({ stage_reach(p), stage_reach(n) });
    EXPECT_EQ(whole.denoiser_radius, 13 + 64);
    whole.band_pixels = 0;
    SureOptions banded = whole;
    banded.band_pixels = 64 * 64;  // 64 own rows, halos of 77 rounded to 96
    ImageBuf a = sure_of(src, chain, whole), b = sure_of(src, chain, banded);
    EXPECT_TRUE(same_pixels(a, b)) << "largest difference " << max_difference(a, b);
}

TEST(SureBands, ComposedInPlaceIsComposed)
{
    // compose_in_place runs each stage after the first on the result before it (the ops
    // may run in place): the same result, for the unprobed run and a colour-only probe, and
    // a failing stage still names itself.
    ImageBuf src = tall_box16();
    PrefilterOptions p;
    NforOptions n;
    CnnOptions c;
    const std::vector<std::pair<std::string, Denoiser>> stages = {
        { "prefilter", [&](ImageBuf& d, const ImageBuf& s) { return prefilter(d, s, p, {}, 2); } },
        { "nfor", [&](ImageBuf& d, const ImageBuf& s) { return nfor(d, s, n, {}, 2); } },
        { "cnn", [&](ImageBuf& d, const ImageBuf& s) { return cnn(d, s, c, {}, 2); } },
    };
    for (bool probe : { false, true }) {
        ImageBuf input = src.copy(OIIO::TypeDesc::FLOAT);
        if (probe)
            input.specmod().attribute("mcdn:colour_only", 1);
        ImageBuf a, b;
        ASSERT_TRUE(compose(stages)(a, input)) << a.geterror();
        ASSERT_TRUE(compose_in_place(stages)(b, input)) << b.geterror();
        EXPECT_EQ(a.spec().channelnames, b.spec().channelnames);
        EXPECT_TRUE(same_pixels(a, b)) << "largest difference " << max_difference(a, b);
    }
    NforOptions bad;
    bad.window_radius = -1;
    ImageBuf failed;
    EXPECT_FALSE(compose_in_place({ stages[0], { "nfor", [&](ImageBuf& d, const ImageBuf& s) {
                                                    return nfor(d, s, bad, {}, 2);
                                                } } })(failed, src));
    EXPECT_EQ(failed.geterror().rfind("nfor: ", 0), 0u) << failed.geterror();
}

TEST(SureBands, ProbingTheCallersFrameGivesSuresResultAndPutsItBack)
{
    // sure_probing_src probes src itself (one band): nfor copies its input with the room
    // sure asks for (core/attributes.h); a callable that copies without it is written into
    // an output of sure's own.
    NforOptions n;
    struct Case {
        ImageBuf frame;
        Denoiser denoiser;
        AovSpec aovs;
    };
    Case cases[] = {
        { tall_box16(), [&](ImageBuf& d, const ImageBuf& s) { return nfor(d, s, n, {}, 2); },
          AovSpec() },
        { noisy_render(48, 200, ramp, 0.01f, 3), box_denoiser(2), generic_spec() },
    };
    for (Case& c : cases) {
        SureOptions options;
        options.aovs = c.aovs;
        const ImageBuf before = c.frame.copy(OIIO::TypeDesc::FLOAT);
        const std::string spec_before = c.frame.spec().to_xml();
        ImageBuf expected, probed;
        ASSERT_TRUE(sure(expected, c.frame, c.denoiser, options, {}, 2)) << expected.geterror();
        ASSERT_TRUE(sure_probing_src(probed, c.frame, c.denoiser, options, {}, 2))
            << probed.geterror();
        EXPECT_EQ(probed.spec().channelnames, expected.spec().channelnames);
        EXPECT_TRUE(same_pixels(expected, probed))
            << "largest difference " << max_difference(expected, probed);
        EXPECT_FALSE(probed.spec().find_attribute("mcdn:output_room"));
        // The caller's frame as it was: pixels and attributes.
        EXPECT_TRUE(same_pixels(c.frame, before));
        EXPECT_EQ(c.frame.spec().to_xml(), spec_before);
    }
}

TEST(SureBands, ProbesAreDrawnPerFramePixel)
{
    // A linear denoiser, two probes, bands of one tile row: any band-relative probe index or
    // probe step would change the divergence.
    ImageBuf src = noisy_render(48, 200, ramp, 0.01f, 3);
    SureOptions whole;
    whole.aovs = generic_spec();
    whole.probes = 2;
    whole.denoiser_radius = 2;
    whole.band_pixels = 0;
    SureOptions banded = whole;
    banded.band_pixels = 48 * 32;  // 32 own rows + halos of 32
    ImageBuf a = sure_of(src, box_denoiser(2), whole), b = sure_of(src, box_denoiser(2), banded);
    EXPECT_TRUE(same_pixels(a, b)) << "largest difference " << max_difference(a, b);
}

TEST(SureBands, TooSmallARadiusShows)
{
    // The test above has teeth: a denoiser that reaches farther than it declares leaves seams.
    ImageBuf src = noisy_render(48, 200, ramp, 0.01f, 3);
    SureOptions whole;
    whole.aovs = generic_spec();
    whole.band_pixels = 0;
    SureOptions banded = whole;
    banded.denoiser_radius = 0;
    banded.band_pixels = 48 * 32;
    ImageBuf a = sure_of(src, box_denoiser(2), whole), b = sure_of(src, box_denoiser(2), banded);
    EXPECT_GT(max_difference(a, b), 1e-4f);
}

TEST(SureBands, ChainRadiusCoversEachStageOnTheInputItGets)
{
    // nfor prefilters itself (77) unless a prefilter ran before it (13 + 64); a stage of
    // unknown reach (the cnn, a callable) makes the chain's unknown: SURE runs it whole.
    EXPECT_EQ(chain_radius({ stage_reach(NforOptions()) }), 77);
    EXPECT_EQ(chain_radius({ stage_reach(PrefilterOptions()), stage_reach(NforOptions()) }), 77);
    EXPECT_EQ(chain_radius({ stage_reach(NforOptions()), stage_reach(PrefilterOptions()) }), 90);
    EXPECT_EQ(chain_radius({ stage_reach(PrefilterOptions()), StageReach() }), -1);
}
