// Reading, merging, validating and writing images.
#include "mcdn/io.h"

#include <cmath>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include "mcdn_test.h"

using namespace mcdn;
using mcdn_test::make_image;

namespace {

std::string box(const std::string& name)
{
    return mcdn_test::test_data("box16/" + name);
}

std::vector<std::string> files_in(const std::string& dir)
{
    std::vector<std::string> files;
    OIIO::Filesystem::get_directory_entries(dir, files);
    return files;
}

ImageBuf merged_box()
{
    ImageBuf merged;
    EXPECT_TRUE(read_inputs(merged, { { box("box_0016spp.exr"), InputKind::Mean },
                                      { box("box_0016spp_var.exr"), InputKind::Variance } }))
        << merged.geterror();
    return merged;
}

AovSet resolve(const ImageBuf& merged, const std::string& preset = "cycles")
{
    AovSpec spec;
    spec.preset = preset;
    AovSet set;
    std::string error;
    EXPECT_TRUE(resolve_aovs(set, spec, merged.spec(), error)) << error;
    return set;
}

void set_value(ImageBuf& buf, int x, int y, int c, float v)
{
    static_cast<float*>(
        buf.localpixels())[(size_t(y) * buf.spec().width + x) * buf.nchannels() + c] = v;
}

}  // namespace

TEST(Io, ReadInputsPrefixesEachFaceAndRecordsWhereChannelsCameFrom)
{
    ImageBuf merged = merged_box();
    const ImageSpec& spec = merged.spec();
    EXPECT_EQ(spec.nchannels, 78);
    EXPECT_EQ(spec.channelnames[0], "ViewLayer.Combined.R");
    EXPECT_EQ(spec.channelnames[39], "variance.ViewLayer.Combined.R");
    EXPECT_EQ(spec.format, OIIO::TypeDesc::FLOAT);
    EXPECT_NE(channel_source(spec, "variance.ViewLayer.Combined.R").find("box_0016spp_var.exr"),
              std::string::npos);
    EXPECT_NE(channel_source(spec, "ViewLayer.Combined.R").find("box_0016spp.exr (-i:as=mean)"),
              std::string::npos);
    // -o writes the render's own channels by default, not the variance
    auto outputs = OIIO::Strutil::splits(spec.get_string_attribute("mcdn:output_channels"), "\n");
    EXPECT_EQ(outputs.size(), 39u);
    // pixel values survive the merge
    ImageBuf var(box("box_0016spp_var.exr"));
    float a[1];
    var.getpixel(10, 20, a, 1);
    float merged_px[78];
    merged.getpixel(10, 20, merged_px, 78);
    EXPECT_EQ(merged_px[39], a[0]);
}

// The first part keeps its names (the beauty, as a reader of part 0 alone sees it); the
// others go behind their part's name.
TEST(Io, MultiPartExrChannelsArePrefixedByPartName)
{
    std::string dir = mcdn_test::temp_dir("multipart");
    std::string path = dir + "/parts.exr";
    ImageSpec beauty(8, 4, 3, OIIO::TypeDesc::FLOAT), albedo(8, 4, 3, OIIO::TypeDesc::FLOAT);
    beauty.channelnames = { "R", "G", "B" };
    beauty.attribute("name", "beauty");
    albedo.channelnames = { "R", "G", "B" };
    albedo.attribute("name", "albedo");
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out && out->supports("multiimage"));
    ImageSpec specs[] = { beauty, albedo };
    ASSERT_TRUE(out->open(path, 2, specs));
    std::vector<float> ones(8 * 4 * 3, 1.0f), twos(8 * 4 * 3, 2.0f);
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, ones.data()));
    ASSERT_TRUE(out->open(path, albedo, OIIO::ImageOutput::AppendSubimage));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, twos.data()));
    ASSERT_TRUE(out->close());

    ImageBuf buf;
    ASSERT_TRUE(read_image(buf, path)) << buf.geterror();
    EXPECT_EQ(buf.spec().channelnames,
              (std::vector<std::string> { "R", "G", "B", "albedo.R", "albedo.G", "albedo.B" }));
    float px[6];
    buf.getpixel(3, 2, px, 6);
    EXPECT_EQ(px[0], 1.0f);
    EXPECT_EQ(px[5], 2.0f);
}

TEST(Io, PfmReadsTopDown)
{
    ImageBuf color;
    ASSERT_TRUE(read_image(color, mcdn_test::test_data("cornell20/color.pfm")));
    EXPECT_EQ(color.spec().width, 64);
    EXPECT_EQ(color.nchannels(), 3);
}

TEST(Io, MismatchedSizesNameTheFile)
{
    std::string dir = mcdn_test::temp_dir("mismatch");
    ImageBuf small = make_image(10, 10, { "R", "G", "B" }, [](int, int, int) { return 0.5f; });
    std::string error;
    ASSERT_TRUE(write_image(small, dir + "/small.exr", WriteOptions(), error)) << error;
    ImageBuf merged;
    EXPECT_FALSE(read_inputs(merged, { { box("box_0016spp.exr"), InputKind::Mean },
                                       { dir + "/small.exr", InputKind::Variance } }));
    EXPECT_NE(merged.geterror().find("small.exr: data window 10x10"), std::string::npos)
        << merged.geterror();
}

TEST(Io, SameChannelFromTwoFilesIsAnError)
{
    ImageBuf merged;
    EXPECT_FALSE(read_inputs(merged, { { box("box_0016spp.exr"), InputKind::Mean },
                                       { box("box_0016spp_A.exr"), InputKind::Mean } }));
    EXPECT_NE(merged.geterror().find("is also in"), std::string::npos) << merged.geterror();
}

TEST(Io, TruncatedAndMissingFilesAreClearErrors)
{
    std::string dir = mcdn_test::temp_dir("truncated");
    std::string path = dir + "/cut.exr";
    {
        std::ifstream in(box("box_0016spp.exr"), std::ios::binary);
        std::string bytes((std::istreambuf_iterator<char>(in)), {});
        std::ofstream(path, std::ios::binary).write(bytes.data(), bytes.size() / 2);
    }
    ImageBuf buf;
    EXPECT_FALSE(read_image(buf, path));
    EXPECT_NE(buf.geterror().find("cut.exr"), std::string::npos) << buf.geterror();
    ImageBuf missing;
    EXPECT_FALSE(read_image(missing, dir + "/nope.exr"));
    EXPECT_NE(missing.geterror().find("nope.exr: no such file"), std::string::npos);
    ImageBuf notdir;
    EXPECT_FALSE(read_inputs(notdir, { { dir, InputKind::Mean } }));
    EXPECT_NE(notdir.geterror().find("no color.pfm"), std::string::npos) << notdir.geterror();
}

TEST(Io, ValidateRejectsNonFiniteColorAndNegativeVariance)
{
    ImageBuf merged = merged_box();
    AovSet set = resolve(merged);
    std::string error;
    ASSERT_TRUE(validate_inputs(merged, set, error)) << error;

    ImageBuf nan = merged.copy(OIIO::TypeDesc::FLOAT);
    set_value(nan, 5, 7, set.channels(Role::Color)[1], std::nanf(""));
    EXPECT_FALSE(validate_inputs(nan, set, error));
    EXPECT_NE(error.find("channel 'ViewLayer.Combined.G'"), std::string::npos) << error;
    EXPECT_NE(error.find("NaN at pixel (5, 7)"), std::string::npos) << error;
    EXPECT_NE(error.find("box_0016spp.exr"), std::string::npos) << error;

    ImageBuf inf = merged.copy(OIIO::TypeDesc::FLOAT);
    set_value(inf, 0, 0, set.channels(Role::Normal)[0], INFINITY);
    EXPECT_FALSE(validate_inputs(inf, set, error));
    EXPECT_NE(error.find("Inf"), std::string::npos) << error;

    ImageBuf huge = merged.copy(OIIO::TypeDesc::FLOAT);
    set_value(huge, 1, 1, set.channels(Role::Color)[0], 1e30f);
    EXPECT_FALSE(validate_inputs(huge, set, error));
    EXPECT_NE(error.find("huge"), std::string::npos) << error;

    ImageBuf negative = merged.copy(OIIO::TypeDesc::FLOAT);
    set_value(negative, 2, 3, set.channels(Role::ColorVariance)[2], -1.0f);
    EXPECT_FALSE(validate_inputs(negative, set, error));
    EXPECT_NE(error.find("negative variance"), std::string::npos) << error;
    EXPECT_NE(error.find("box_0016spp_var.exr"), std::string::npos) << error;

    // A render's NaN feature variance (pixels without a feature sample) is accepted.
    ImageBuf nan_feature_var = merged.copy(OIIO::TypeDesc::FLOAT);
    set_value(nan_feature_var, 2, 3, set.channels(Role::AlbedoVariance)[0], std::nanf(""));
    EXPECT_TRUE(validate_inputs(nan_feature_var, set, error)) << error;
}

TEST(Io, TungstenFixtureWithNaNFeatureVarianceValidates)
{
    ImageBuf merged;
    ASSERT_TRUE(read_inputs(merged, { { mcdn_test::test_data("cornell20"), InputKind::Mean } }));
    AovSet set = resolve(merged, "tungsten");
    std::string error;
    EXPECT_TRUE(validate_inputs(merged, set, error)) << error;
}

TEST(Io, WriteKeepsChannelsAndMetadataAndLeavesNoTemporaryFile)
{
    ImageBuf merged = merged_box();
    std::string dir = mcdn_test::temp_dir("write");
    std::string path = dir + "/out.exr";
    std::string error;
    WriteOptions options;
    options.datatype = OIIO::TypeDesc::HALF;
    ASSERT_TRUE(write_image(merged, path, options, error)) << error;
    EXPECT_EQ(files_in(dir).size(), 1u);
    auto in = OIIO::ImageInput::open(path);
    ASSERT_TRUE(in);
    const ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.nchannels, 39);  // the render's channels, not the variance
    EXPECT_EQ(spec.format, OIIO::TypeDesc::HALF);
    EXPECT_EQ(spec.get_string_attribute("compression"), "zip");
    EXPECT_EQ(spec.get_string_attribute("combine:K"), "8");   // the render's metadata
    EXPECT_EQ(spec.get_string_attribute("mcdn:inputs"), "");  // bookkeeping dropped
}

TEST(Io, FailedWriteLeavesNothingBehind)
{
    ImageBuf merged = merged_box();
    std::string dir = mcdn_test::temp_dir("failwrite");
    std::string error;
    WriteOptions options;
    options.channels = { "ViewLayer.Combined.R", "no.such.channel" };
    EXPECT_FALSE(write_image(merged, dir + "/out.exr", options, error));
    EXPECT_NE(error.find("no.such.channel"), std::string::npos) << error;
    // A file where the output's folder would be.
    ASSERT_TRUE(OIIO::Filesystem::write_text_file(dir + "/file", "x"));
    EXPECT_FALSE(write_image(merged, dir + "/file/out.exr", WriteOptions(), error));
    EXPECT_NE(error.find("is not a folder"), std::string::npos) << error;
    OIIO::Filesystem::remove(dir + "/file");
    EXPECT_TRUE(files_in(dir).empty());
}

// Unless told otherwise, each channel keeps the type it had in the render's file and the
// file its compression (a half DWAA beauty with float depth comes back so, as oiiotool
// keeps them); a missing folder is made.
TEST(Io, OutputKeepsTheInputsTypesAndCompression)
{
    std::string dir = mcdn_test::temp_dir("keeptypes");
    const std::string depth = "ViewLayer.Depth.Z";
    ASSERT_EQ(std::system(("oiiotool " + box("box_0016spp.exr") + " -d half -d " + depth
                           + "=float --compression dwaa:45 -o " + dir + "/in.exr")
                              .c_str()),
              0);
    ImageBuf merged;
    ASSERT_TRUE(read_inputs(merged, { { dir + "/in.exr", InputKind::Mean } })) << merged.geterror();
    std::string error;
    ASSERT_TRUE(write_image(merged, dir + "/sub/out.exr", WriteOptions(), error)) << error;
    auto in = OIIO::ImageInput::open(dir + "/sub/out.exr");
    ASSERT_TRUE(in);
    const OIIO::ImageSpec& spec = in->spec();
    EXPECT_EQ(spec.get_string_attribute("compression"), "dwaa");
    EXPECT_EQ(spec.channelformat(spec.channelindex("ViewLayer.Combined.R")), OIIO::TypeHalf);
    EXPECT_EQ(spec.channelformat(spec.channelindex(depth)), OIIO::TypeFloat);
    WriteOptions asked;
    asked.datatype = OIIO::TypeFloat;
    asked.compression = "piz";
    ASSERT_TRUE(write_image(merged, dir + "/out2.exr", asked, error)) << error;
    auto in2 = OIIO::ImageInput::open(dir + "/out2.exr");
    ASSERT_TRUE(in2);
    EXPECT_EQ(in2->spec().get_string_attribute("compression"), "piz");
    EXPECT_EQ(in2->spec().channelformat(0), OIIO::TypeFloat);
}

// RowWriter writes the file write_image writes, row band by row band; one left unclosed
// (a chain that failed halfway) leaves neither the file nor its temporary.
TEST(Io, RowWriterWritesWhatWriteImageWritesAndLeavesNothingUnclosed)
{
    ImageBuf merged = merged_box();
    std::string dir = mcdn_test::temp_dir("rowwriter");
    std::string error;
    ASSERT_TRUE(write_image(merged, dir + "/whole.exr", WriteOptions(), error)) << error;
    const ROI all = merged.roi();
    const int half = all.ybegin + all.height() / 2;
    {
        RowWriter writer;
        ASSERT_TRUE(writer.open(merged.spec(), dir + "/rows.exr", WriteOptions(), error)) << error;
        ROI top = all, bottom = all;
        top.yend = bottom.ybegin = half;
        EXPECT_FALSE(writer.write_rows(merged, bottom, error));  // out of order
        ASSERT_TRUE(writer.write_rows(merged, top, error)) << error;
        ASSERT_TRUE(writer.write_rows(merged, bottom, error)) << error;
        ASSERT_TRUE(writer.close(error)) << error;
    }
    ImageBuf whole(dir + "/whole.exr"), rows(dir + "/rows.exr");
    ASSERT_EQ(whole.spec().channelnames, rows.spec().channelnames);
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(whole, rows, 0, 0).maxerror, 0.0);
    {
        RowWriter writer;
        ASSERT_TRUE(writer.open(merged.spec(), dir + "/unclosed.exr", WriteOptions(), error));
        ROI top = all;
        top.yend = half;
        ASSERT_TRUE(writer.write_rows(merged, top, error)) << error;
        EXPECT_FALSE(writer.close(error));  // rows missing
    }
    for (const std::string& f : files_in(dir)) {
        const std::string name = OIIO::Filesystem::filename(f);
        EXPECT_TRUE(name == "whole.exr" || name == "rows.exr") << f;
    }
}

// RowWriter hands the file a chunk of rows at a time: a band taller than a chunk, starting
// off the chunk grid, is written as write_image writes it.
TEST(Io, RowWriterWritesBandsTallerThanItsChunks)
{
    ImageSpec spec(40, 700, 5, OIIO::TypeDesc::FLOAT);
    spec.y = -3;
    ImageBuf frame(spec);
    OIIO::ImageBufAlgo::noise(frame, "uniform", 0.0f, 4.0f, false, 7);
    const std::string dir = mcdn_test::temp_dir("rowchunks");
    std::string error;
    ASSERT_TRUE(write_image(frame, dir + "/whole.exr", WriteOptions(), error)) << error;
    RowWriter writer;
    ASSERT_TRUE(writer.open(spec, dir + "/rows.exr", WriteOptions(), error)) << error;
    ROI top = frame.roi(), bottom = frame.roi();
    top.yend = bottom.ybegin = 30;
    ASSERT_TRUE(writer.write_rows(frame, top, error)) << error;
    ASSERT_TRUE(writer.write_rows(frame, bottom, error)) << error;  // 667 rows
    ASSERT_TRUE(writer.close(error)) << error;
    ImageBuf whole(dir + "/whole.exr"), rows(dir + "/rows.exr");
    EXPECT_EQ(OIIO::ImageBufAlgo::compare(whole, rows, 0, 0).maxerror, 0.0);
    EXPECT_EQ(rows.spec().y, -3);
}

// Renderers write tiled EXRs (Arnold's and RenderMan's drivers often do): read whole or for
// the roles alone (rows of tiles, not scanlines, from a tiled file), every input reads the
// same as its scanline original. A partial last row and column of tiles included.
TEST(Io, TiledFilesReadAsTheirScanlineOriginals)
{
    const std::string dir = mcdn_test::temp_dir("tiled");
    std::vector<InputFile> scanline, tiled;
    for (const auto& [name, kind] :
         { std::pair<std::string, InputKind> { "box_0016spp.exr", InputKind::Mean },
           { "box_0016spp_var.exr", InputKind::Variance },
           { "box_0016spp_A.exr", InputKind::HalfA },
           { "box_0016spp_B.exr", InputKind::HalfB } }) {
        ImageBuf in(box(name));
        ASSERT_TRUE(in.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << in.geterror();
        in.set_write_tiles(48, 24);  // does not divide the 128² frame
        const std::string path = dir + "/" + name;
        ASSERT_TRUE(in.write(path)) << in.geterror();
        auto check = OIIO::ImageInput::open(path);
        ASSERT_TRUE(check && check->spec().tile_width == 48) << path;
        scanline.push_back({ box(name), kind });
        tiled.push_back({ path, kind });
    }
    for (bool only_roles : { false, true }) {
        InputSelection selection;
        selection.only_roles = only_roles;
        selection.aovs.preset = "cycles";
        ImageBuf a, b;
        ASSERT_TRUE(read_inputs(a, scanline, selection)) << a.geterror();
        ASSERT_TRUE(read_inputs(b, tiled, selection)) << b.geterror();
        ASSERT_EQ(a.nchannels(), b.nchannels());
        const OIIO::ImageBufAlgo::CompareResults cmp =
            OIIO::ImageBufAlgo::compare(a, b, 0.0f, 0.0f);
        EXPECT_EQ(cmp.nfail, 0u) << (only_roles ? "roles only" : "every channel");
        EXPECT_EQ(cmp.maxerror, 0.0);
    }
}

// Files are read through OpenEXR's C core where it reads the codec as the C++ library does
// (io.cpp: core_reads). Every codec a renderer may write, float and half, scanline and
// tiled, layer-prefixed names, Inf and NaN among the values: read_image gives the C++
// library's bits exactly, and DWA/B44 files (which the core in OpenEXR 3.1 cannot read, or
// reads otherwise) are still read. A codec that the core reads differently in a later
// OpenEXR fails here, not in a user's frame.
TEST(Io, EveryExrCodecReadsAsTheCxxLibraryReadsIt)
{
    const std::string dir = mcdn_test::temp_dir("codecs");
    const int w = 45, h = 37, nch = 5;
    std::vector<float> values(size_t(w) * h * nch);
    uint32_t state = 12345;
    for (size_t i = 0; i < values.size(); ++i) {
        state = state * 1664525u + 1013904223u;
        const float u = float(state >> 8) / float(1 << 24);
        values[i] = (u - 0.3f) * std::exp(12.0f * u - 4.0f);
    }
    values[3] = std::numeric_limits<float>::infinity();
    values[17] = std::numeric_limits<float>::quiet_NaN();
    for (const char* codec :
         { "none", "rle", "zips", "zip", "piz", "pxr24", "b44", "b44a", "dwaa", "dwab" })
        for (const OIIO::TypeDesc type : { OIIO::TypeDesc::FLOAT, OIIO::TypeDesc::HALF })
            for (int tile : { 0, 16 }) {
                ImageSpec spec(w, h, nch, type);
                spec.channelnames = { "ViewLayer.Combined.R", "ViewLayer.Combined.G",
                                      "ViewLayer.Combined.B", "albedo.R", "N.X" };
                spec.attribute("compression", codec);
                spec.tile_width = spec.tile_height = tile;
                const std::string path =
                    OIIO::Strutil::fmt::format("{}/{}_{}_{}.exr", dir, codec, type.c_str(), tile);
                auto out = OIIO::ImageOutput::create(path);
                ASSERT_TRUE(out && out->open(path, spec)
                            && out->write_image(OIIO::TypeDesc::FLOAT, values.data())
                            && out->close())
                    << path;
                int before = 0;
                OIIO::getattribute("openexr:core", before);
                OIIO::attribute("openexr:core", 0);
                ImageBuf cxx(path);
                const bool read_cxx = cxx.read(0, 0, true, OIIO::TypeDesc::FLOAT);
                OIIO::attribute("openexr:core", before);
                ASSERT_TRUE(read_cxx) << path << ": " << cxx.geterror();
                ImageBuf ours;
                ASSERT_TRUE(read_image(ours, path)) << path << ": " << ours.geterror();
                ASSERT_EQ(ours.nchannels(), cxx.nchannels()) << path;
                const size_t n = size_t(w) * h * nch;
                EXPECT_EQ(std::memcmp(ours.localpixels(), cxx.localpixels(), n * sizeof(float)), 0)
                    << path;
            }
}

// A damaged header that OpenEXR's core parses as a scanline part with a tile description
// leaves its rows per block 0, and OIIO 2.4's core reader divides by them (a fuzzer found the
// SIGFPE): such a file is read by the C++ library, which names what is wrong.
TEST(Io, ScanlineFlagOnATiledFileIsAnErrorNotACrash)
{
    const std::string dir = mcdn_test::temp_dir("scanline_flag");
    const std::string tiled = dir + "/tiled.exr", damaged = dir + "/damaged.exr";
    ImageBuf src = make_image(6, 5, { "R", "G", "B" },
                              [](int x, int y, int c) { return float(x + 10 * y + 100 * c); });
    src.specmod().tile_width = 1;
    src.specmod().tile_height = 4;
    src.specmod().attribute("compression", "rle");
    src.set_write_tiles(1, 4);
    ASSERT_TRUE(src.write(tiled)) << src.geterror();
    std::ifstream in(tiled, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    ASSERT_GT(bytes.size(), 8u);
    ASSERT_TRUE(bytes[5] & 0x02) << "OpenEXR's single-part tiled flag";
    bytes[5] = char(bytes[5] & ~0x02);
    std::ofstream(damaged, std::ios::binary) << bytes;
    ImageBuf ours;
    EXPECT_FALSE(read_image(ours, damaged));
    EXPECT_NE(ours.geterror().find(damaged), std::string::npos) << ours.geterror();
}

// K seed renders: the mean, the variance of the mean (sample variance over K), the means of
// the first and last K/2 seeds; identifiers (Cryptomatte) are the first seed's, without faces.
TEST(Io, SeedsAreTheirMeanWithItsVarianceAndHalves)
{
    const std::string dir = mcdn_test::temp_dir("io_seeds");
    const std::vector<std::string> names = { "R", "G", "B", "CryptoObject00.R" };
    const float values[4] = { 1.0f, 2.0f, 4.0f, 9.0f };
    std::vector<std::string> seeds;
    for (int s = 0; s < 4; ++s) {
        seeds.push_back(dir + "/seed" + std::to_string(s) + ".exr");
        ImageBuf seed = make_image(3, 2, names, [&](int x, int, int c) {
            return c == 3 ? float(100 + s) : values[s] * float(c + 1) + float(x);
        });
        ASSERT_TRUE(seed.write(seeds.back()));
    }
    InputFile input(seeds[0]);
    input.seeds = seeds;
    ImageBuf merged;
    ASSERT_TRUE(read_inputs(merged, { input })) << merged.geterror();
    const ImageSpec& spec = merged.spec();
    for (const char* name : { "variance.R", "A.G", "B.B" })
        EXPECT_GE(spec.channelindex(name), 0) << name;
    EXPECT_LT(spec.channelindex("variance.CryptoObject00.R"), 0);
    EXPECT_EQ(spec.get_string_attribute("mcdn:output_channels"), "R\nG\nB\nCryptoObject00.R");
    // Channel G (c = 1) at x = 2: seeds 2*{1,2,4,9} + 2 = 4, 6, 10, 20.
    auto at = [&](const char* name) { return merged.getchannel(2, 1, 0, spec.channelindex(name)); };
    const double mean = (4 + 6 + 10 + 20) / 4.0;
    const double var = ((4 - mean) * (4 - mean) + (6 - mean) * (6 - mean)
                        + (10 - mean) * (10 - mean) + (20 - mean) * (20 - mean))
                       / 3.0 / 4.0;
    EXPECT_FLOAT_EQ(at("G"), float(mean));
    EXPECT_FLOAT_EQ(at("variance.G"), float(var));
    EXPECT_FLOAT_EQ(at("A.G"), 5.0f);
    EXPECT_FLOAT_EQ(at("B.G"), 15.0f);
    EXPECT_FLOAT_EQ(at("CryptoObject00.R"), 100.0f);
    // An odd K: no halves (they would not have the same samples), the variance all the same.
    input.seeds.pop_back();
    ImageBuf three;
    ASSERT_TRUE(read_inputs(three, { input })) << three.geterror();
    EXPECT_GE(three.spec().channelindex("variance.R"), 0);
    EXPECT_LT(three.spec().channelindex("A.R"), 0);
}
