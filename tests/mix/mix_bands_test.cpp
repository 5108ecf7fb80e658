// The mix of a large frame runs in bands (MixOptions::band_pixels): the result must be the
// whole-frame run's (the t-test's sigma_s is the frame's; the halo covers alpha's reach).
#include "mcdn/mix.h"

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/sure.h"
#include "same_pixels.h"
#include "synthetic.h"

using namespace mcdn;
using namespace mcdn_test;

namespace {

float stripes(int x, int y, int c)
{
    return ((x / 6 + y / 9) % 3) * 0.3f + 0.05f * c + 0.002f * y;
}

// sure's output for a 48x256 render denoised by a box blur (biased on the stripes), the
// blur's tiles kept where SURE finds them worse (the safety net would make them the render,
// leaving the mix nothing to mix there).
ImageBuf sure_output()
{
    SureOptions o;
    o.aovs = generic_spec();
    o.fallback = false;
    ImageBuf out;
    EXPECT_TRUE(sure(out, noisy_render(48, 256, stripes, 0.004f, 5), box_denoiser(2), o))
        << out.geterror();
    return out;
}

std::pair<ImageBuf, ImageBuf> whole_and_banded(MixOptions o)
{
    const ImageBuf src = sure_output();
    o.aovs = generic_spec();
    o.output_alpha = true;
    o.band_pixels = 0;
    ImageBuf whole = mix(src, o, {}, 2);
    o.band_pixels = 48 * 32;  // 8 bands of 32 rows, halos of 32
    ImageBuf banded = mix(src, o, {}, 2);
    EXPECT_FALSE(whole.has_error()) << whole.geterror();
    EXPECT_FALSE(banded.has_error()) << banded.geterror();
    // Something to compare: alpha' is neither 0 nor 1 throughout.
    const int a = whole.spec().channelindex("mix.alpha.G");
    auto stats = OIIO::ImageBufAlgo::computePixelStats(whole);
    EXPECT_GT(stats.max[a], 0.1f);
    EXPECT_LT(stats.min[a], 0.9f);
    return { whole, banded };
}

}  // namespace

TEST(MixBands, AnalyticInBandsEqualsTheWholeFrame)
{
    auto [whole, banded] = whole_and_banded({});
    EXPECT_TRUE(same_pixels(whole, banded))
        << "largest difference " << max_difference(whole, banded);
}

TEST(MixBands, NetInBandsEqualsTheWholeFrame)
{
    // The network's tiles fall differently in a band (oneDNN may sum in another order):
    // equal within float round-off, as tiled inference is (tests/nn).
    MixOptions o;
    o.model = MixOptions::Model::Net;
    auto [whole, banded] = whole_and_banded(o);
    EXPECT_LT(max_difference(whole, banded), 1e-5f);
}

// In place (dst is src: what a chain does with its own sure result) is the same as into a
// new buffer, whole (no copy) and in bands (a band's halo must not read its neighbour's z).
TEST(MixBands, InPlaceEqualsIntoANewBuffer)
{
    for (int64_t band_pixels : { int64_t(0), int64_t(48 * 32) }) {
        MixOptions o;
        o.aovs = generic_spec();
        o.output_alpha = true;
        o.band_pixels = band_pixels;
        const ImageBuf src = sure_output();
        ImageBuf expected = mix(src, o, {}, 2), in_place = src.copy(OIIO::TypeDesc::FLOAT);
        ASSERT_TRUE(mix(in_place, in_place, o, {}, 2)) << in_place.geterror();
        EXPECT_TRUE(same_pixels(expected, in_place))
            << "bands of " << band_pixels << " pixels: largest difference "
            << max_difference(expected, in_place);
    }
}
