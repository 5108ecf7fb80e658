// A frame read a band of rows at a time (mcdn::InputRows, run_chain on a RowReader) gives what
// the frame read whole gives: the same rows from scanline and tiled files, with and without a
// selection of channels, and the same chain result.
#include <algorithm>
#include <gtest/gtest.h>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>

#include "mcdn/chain.h"
#include "mcdn/io.h"
#include "mcdn/stages.h"

#include "fixtures.h"

using namespace mcdn;
using OIIO::ImageBuf;

namespace {

const char* const kFaces[] = { "", "_var", "_A", "_B" };
const InputKind kKinds[] = { InputKind::Mean, InputKind::Variance, InputKind::HalfA,
                             InputKind::HalfB };

// box16's four files, each stacked eight times (64x512), written to `dir` scanline or tiled.
std::vector<InputFile> tall_files(const std::string& dir, bool tiled)
{
    std::vector<InputFile> files;
    for (int f = 0; f < 4; ++f) {
        ImageBuf one;
        EXPECT_TRUE(
            read_image(one, mcdn_test::test_data("box16/box_0016spp") + kFaces[f] + ".exr"));
        OIIO::ImageSpec spec = one.spec();
        spec.height = spec.full_height = 8 * one.spec().height;
        ImageBuf tall(spec);
        for (int i = 0; i < 8; ++i)
            EXPECT_TRUE(OIIO::ImageBufAlgo::paste(tall, 0, i * one.spec().height, 0, 0, one));
        if (tiled)
            tall.set_write_tiles(32, 32);
        const std::string path = dir + "/box" + kFaces[f] + ".exr";
        EXPECT_TRUE(tall.write(path)) << tall.geterror();
        files.push_back({ path, kKinds[f] });
    }
    return files;
}

void expect_rows_match(const std::vector<InputFile>& files, const InputSelection& selection)
{
    ImageBuf whole;
    ASSERT_TRUE(read_inputs(whole, files, selection)) << whole.geterror();
    InputRows rows;
    std::string error;
    ASSERT_TRUE(rows.open(files, selection, error)) << error;
    EXPECT_EQ(rows.spec().channelnames, whole.spec().channelnames);
    ImageBuf band;
    // Rows on and off the 32-row tiles, and the frame's last rows.
    for (auto [y0, y1] : { std::pair { 0, 64 }, { 40, 97 }, { 100, 103 }, { 480, 512 } }) {
        ASSERT_TRUE(rows.read(band, y0, y1, error)) << error;
        ASSERT_EQ(band.spec().y, y0);
        ASSERT_EQ(band.spec().height, y1 - y0);
        const auto cmp = OIIO::ImageBufAlgo::compare(band, whole, 0, 0, band.roi());
        EXPECT_EQ(cmp.maxerror, 0.0) << y0 << "-" << y1;
        EXPECT_EQ(cmp.nfail, 0u);
    }
    // Only the colour: the half files are not decoded, their channels zero.
    const int r = rows.spec().channelindex("ViewLayer.Combined.R");
    const int a = rows.spec().channelindex("A.ViewLayer.Combined.R");
    ASSERT_GE(r, 0);
    ASSERT_GE(a, 0);
    std::vector<bool> color(size_t(rows.spec().nchannels), false);
    color[size_t(r)] = true;
    ImageBuf some;
    ASSERT_TRUE(rows.read(some, 32, 64, error, color)) << error;
    EXPECT_EQ(some.getchannel(0, 40, 0, a), 0.0f);
    EXPECT_NE(whole.getchannel(0, 40, 0, a), 0.0f);
    EXPECT_EQ(some.getchannel(5, 40, 0, r), whole.getchannel(5, 40, 0, r));
    EXPECT_FALSE(rows.read(some, 500, 520, error));
    EXPECT_NE(error.find("outside the frame"), std::string::npos) << error;
}

// The chain on the files read a band at a time, against the chain in bands on the frame in
// memory (tests/chain/bands_test.cpp: that is the whole frame's result).
void expect_chain_match(const std::vector<InputFile>& files, const ChainOptions& o,
                        double tolerance)
{
    ImageBuf whole;
    ASSERT_TRUE(read_inputs(whole, files)) << whole.geterror();
    ImageBuf expected;
    ASSERT_TRUE(run_chain(expected, whole, o)) << expected.geterror();

    InputRows rows;
    std::string error;
    ASSERT_TRUE(rows.open(files, InputSelection(), error)) << error;
    int reads = 0;
    auto read = [&](ImageBuf& band, int y0, int y1, const std::vector<bool>& channels,
                    std::string& read_error) {
        ++reads;
        return rows.read(band, y0, y1, read_error, channels);
    };
    ImageBuf streamed;
    auto sink = [&](const ImageBuf& band, OIIO::ROI own, std::string&) {
        own.chbegin = 0;  // every channel of the result (the input's ROI has fewer)
        own.chend = band.nchannels();
        if (!streamed.initialized()) {
            OIIO::ImageSpec spec = band.spec();
            spec.y = whole.spec().y;
            spec.height = whole.spec().height;
            streamed.reset(spec);
        }
        return OIIO::ImageBufAlgo::paste(streamed, own.xbegin, own.ybegin, 0, 0,
                                         OIIO::ImageBufAlgo::cut(band, own));
    };
    ASSERT_TRUE(run_chain(rows.spec(), read, o, sink, error)) << error;
    if (o.band_pixels > 0)
        EXPECT_GT(reads, 2);  // the light pass and the bands
    else
        EXPECT_EQ(reads, 1);
    ASSERT_EQ(streamed.spec().channelnames, expected.spec().channelnames);
    const auto cmp = OIIO::ImageBufAlgo::compare(streamed, expected, 0, 0);
    EXPECT_LE(cmp.maxerror, tolerance)
        << " at " << cmp.maxx << "," << cmp.maxy << " channel " << cmp.maxc << " ("
        << expected.spec().channel_name(cmp.maxc) << ")";
}

}  // namespace

TEST(Streamed, RowsAreTheWholeFramesRows)
{
    for (bool tiled : { false, true }) {
        const auto files =
            tall_files(mcdn_test::temp_dir(tiled ? "streamed_rows_tiled" : "streamed_rows"), tiled);
        expect_rows_match(files, InputSelection());
        InputSelection roles;
        roles.only_roles = true;
        expect_rows_match(files, roles);
    }
}

TEST(Streamed, ChainOnRowsIsTheChainOnTheFrame)
{
    const auto files = tall_files(mcdn_test::temp_dir("streamed_chain"), false);
    ChainOptions o;
    o.band_pixels = 64 * 64;
    o.band_halos = 0;
    o.stages = { "cnn", "sure", "mix" };
    o.settings = { { "mix.model", "analytic" } };
    expect_chain_match(files, o, 0.0);
    o.stages = { "prefilter", "nfor" };
    o.settings = {};
    expect_chain_match(files, o, 0.0);
    // One band: the frame is read whole, and the chain runs on it as its own (sure probes
    // it in place; a prefilter's features are put back from it after).
    o.band_pixels = 0;
    o.stages = { "cnn" };
    expect_chain_match(files, o, 0.0);
    o.stages = { "cnn", "sure", "mix" };
    o.settings = { { "mix.model", "analytic" } };
    expect_chain_match(files, o, 0.0);
    o.stages = { "prefilter", "nfor", "sure", "mix" };
    expect_chain_match(files, o, 0.0);
}

// ChainOptions::band_halos: a band holds at least that many halos of its own rows whatever
// band_pixels says (fewer rows computed again); 0: band_pixels alone.
TEST(Streamed, BandsHoldAtLeastBandHalosOfTheirHalo)
{
    const auto files = tall_files(mcdn_test::temp_dir("streamed_halos"), false);  // 512 rows
    InputRows rows;
    std::string error;
    ASSERT_TRUE(rows.open(files, InputSelection(), error)) << error;
    ChainOptions o;
    o.stages = { "prefilter", "nfor" };  // reach 77: a halo of 96 rows on the 32-row grid
    o.band_pixels = int64_t(rows.spec().width) * 32;
    for (int halos : { 0, 1, 2 }) {
        o.band_halos = halos;
        std::vector<int> own_rows;
        auto read = [&](ImageBuf& band, int y0, int y1, const std::vector<bool>& channels,
                        std::string& read_error) {
            return rows.read(band, y0, y1, read_error, channels);
        };
        auto sink = [&](const ImageBuf&, OIIO::ROI own, std::string&) {
            own_rows.push_back(own.height());
            return true;
        };
        ASSERT_TRUE(run_chain(rows.spec(), read, o, sink, error)) << error;
        const int fewest = *std::min_element(own_rows.begin(), own_rows.end() - 1);
        if (halos == 0)  // 32 rows each, the first and the last 32 + 96: cuts of 224 rows
            EXPECT_EQ(own_rows, std::vector<int>({ 128, 32, 32, 32, 32, 32, 32, 32, 32, 128 }));
        else
            EXPECT_GE(fewest, halos * 96) << halos << " halos, " << own_rows.size() << " bands";
    }
}

// A chain without the CNN reads the light split's passes only as the extras it denoises
// (their faces: NFOR's own halves of each), and only the output's features are put back after
// a prefilter: what -o writes is what reading every channel and putting every face back gives.
TEST(Streamed, ChainWithoutTheCnnReadsNoFaceOfTheLightSplit)
{
    const auto files = tall_files(mcdn_test::temp_dir("streamed_split"), false);
    InputSelection selection;
    selection.only_roles = true;
    selection.light_split = false;
    ImageBuf all, some;
    ASSERT_TRUE(read_inputs(all, files)) << all.geterror();
    ASSERT_TRUE(read_inputs(some, files, selection)) << some.geterror();
    for (const char* name :
         { "variance.ViewLayer.DiffDir.R", "A.ViewLayer.GlossInd.G", "B.ViewLayer.Emit.B" }) {
        EXPECT_GE(all.spec().channelindex(name), 0) << name;
        EXPECT_GE(some.spec().channelindex(name), 0) << name;
    }
    for (const char* name :
         { "ViewLayer.DiffDir.R", "variance.ViewLayer.Combined.R", "A.ViewLayer.Denoising Albedo.G",
           "variance.ViewLayer.Denoising Depth.Z" })
        EXPECT_GE(some.spec().channelindex(name), 0) << name;

    ChainOptions o;
    o.stages = { "prefilter", "nfor" };
    o.band_pixels = 0;
    ImageBuf expected, result;
    ASSERT_TRUE(run_chain(expected, all, o)) << expected.geterror();
    o.output_channels_only = true;
    ASSERT_TRUE(run_chain(result, some, o)) << result.geterror();
    mcdn_test::expect_output_channels_equal(expected, result, all);
}

// What a chain reads of the variance and half files, by its stages (every front end's
// selection: mcdntool, the OIIO plugin's recipes, Python's read_inputs(chain=...)).
TEST(Streamed, EachChainReadsWhatItsStagesRead)
{
    using Stages = std::vector<std::pair<std::string, Settings>>;
    const InputSelection oidn =
        chain_input_selection({ { "oidn", {} }, { "sure", {} }, { "mix", {} } }, true);
    EXPECT_TRUE(oidn.only_roles);
    EXPECT_FALSE(oidn.halves || oidn.light_split || oidn.all_variances);
    const InputSelection nfor =
        chain_input_selection({ { "prefilter", {} }, { "nfor", {} } }, true);
    EXPECT_TRUE(nfor.halves && nfor.all_variances);
    EXPECT_FALSE(nfor.light_split);
    const InputSelection cnn =
        chain_input_selection({ { "cnn", { { "features", "a,b" } } } }, true);
    EXPECT_TRUE(cnn.light_split && cnn.all_variances);
    EXPECT_FALSE(cnn.halves);
    EXPECT_EQ(cnn.extra_features, (std::vector<std::string> { "a", "b" }));
    // A chain as run_chain takes it: each stage gets its own "stage.key" settings.
    EXPECT_EQ(chain_input_selection(std::vector<std::string> { "nfor", "cnn" },
                                    { { "cnn.features", "a,b" }, { "nfor.features", "c" } }, true)
                  .extra_features,
              (std::vector<std::string> { "c", "a", "b" }));
    // Without a variance the stages take the halves' difference.
    EXPECT_TRUE(chain_input_selection({ { "cnn", {} } }, false).halves);
    const InputSelection none = chain_input_selection(Stages(), true);
    EXPECT_TRUE(none.only_roles);
    EXPECT_FALSE(none.halves || none.light_split || none.all_variances);
    EXPECT_FALSE(chain_input_selection({ { "nosuch", {} } }, true).only_roles);  // everything
}
