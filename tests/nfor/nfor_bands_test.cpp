// Large frames run in horizontal bands (ops/bands.h): the result must equal the
// whole-frame run, which holds only when each band's halo covers the op's receptive radius —
// too small a radius shows up as seams at the band edges.
#include <OpenImageIO/imagebufalgo.h>

#include "ops/bands.h"
#include "mcdn/io.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "fixtures.h"
#include "mcdn_test.h"

using namespace mcdn;

namespace {

// Largest difference over every channel and pixel, relative to the channel's largest value.
float max_relative_difference(const ImageBuf& a, const ImageBuf& b)
{
    EXPECT_EQ(a.spec().channelnames, b.spec().channelnames);
    EXPECT_EQ(a.roi(), b.roi());
    float worst = 0.0f;
    for (int c = 0; c < a.nchannels(); ++c) {
        auto stats_a = OIIO::ImageBufAlgo::computePixelStats(a);
        float scale = std::max({ std::abs(stats_a.min[c]), std::abs(stats_a.max[c]), 1e-6f });
        for (OIIO::ImageBuf::ConstIterator<float> pa(a), pb(b); !pa.done(); ++pa, ++pb)
            worst = std::max(worst, std::abs(pa[c] - pb[c]) / scale);
    }
    return worst;
}

}  // namespace

TEST(Bands, NforInBandsEqualsTheWholeFrame)
{
    ImageBuf src = mcdn_test::tall_box16();
    NforOptions whole;
    whole.band_pixels = 0;
    NforOptions banded;
    // Four bands of 64 rows, each with a 96-row halo (77 rounded up to whole tiles).
    banded.band_pixels = int64_t(src.spec().width) * 64;
    ImageBuf a = nfor(src, whole, {}, 2), b = nfor(src, banded, {}, 2);
    ASSERT_FALSE(a.has_error()) << a.geterror();
    ASSERT_FALSE(b.has_error()) << b.geterror();
    EXPECT_EQ(max_relative_difference(a, b), 0.0f);
}

TEST(Bands, PrefilterInBandsEqualsTheWholeFrame)
{
    ImageBuf src = mcdn_test::tall_box16();
    PrefilterOptions whole, banded;
    whole.band_pixels = 0;
    banded.band_pixels = int64_t(src.spec().width) * 32;  // 8 bands of 32 rows, halo 13 -> 32
    ImageBuf a = prefilter(src, whole, {}, 2), b = prefilter(src, banded, {}, 2);
    ASSERT_FALSE(a.has_error()) << a.geterror();
    ASSERT_FALSE(b.has_error()) << b.geterror();
    EXPECT_EQ(max_relative_difference(a, b), 0.0f);
    EXPECT_EQ(b.spec().get_int_attribute("mcdn:prefiltered", 0), 1);
}

// The tests above have teeth: a halo well short of NFOR's reach (32 rows against 77 at the default
// settings) changes pixels near the band edges. (On this fixture 50 rows already give the
// whole-frame result: far NL-means weights underflow to exactly 0; 77 is the bound for any
// image.)
TEST(Bands, TooSmallAHaloShows)
{
    ImageBuf src = mcdn_test::tall_box16();
    NforOptions o;
    o.band_pixels = 0;
    ImageBuf a = nfor(src, o, {}, 2);
    ImageBuf b;
    ASSERT_TRUE(run_in_bands(b, src, 30, int64_t(src.spec().width) * 64,
                             [&](ImageBuf& d, const ImageBuf& s) { return nfor(d, s, o, {}, 2); }));
    EXPECT_GT(max_relative_difference(a, b), 1e-4f);
}
