// What a TD meets in a pipeline: the silent cases of issue 20 are each an error, a warning or
// a documented choice.
#include <cmath>
#include <map>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>

#include "mcdn_test.h"

using mcdn_test::quote;
using mcdn_test::run_mcdntool;

namespace {

std::string box(const std::string& name)
{
    return quote(mcdn_test::test_data("box16/" + name));
}

/// Three frames of box16 (render and variance) in `dir`: shot.0001.exr ... and shot_var.*.
void make_shot(const std::string& dir)
{
    for (int f : { 1, 2, 3 })
        for (const char* face : { "", "_var" })
            OIIO::Filesystem::copy(
                mcdn_test::test_data(std::string("box16/box_0016spp") + face + ".exr"),
                OIIO::Strutil::fmt::format("{}/shot{}.{:04d}.exr", dir, face, f));
}

bool same_channel(const std::string& a, const std::string& b, const std::string& channel)
{
    OIIO::ImageBuf x(a), y(b);
    const int cx = x.spec().channelindex(channel), cy = y.spec().channelindex(channel);
    if (cx < 0 || cy < 0)
        return false;
    auto d = OIIO::ImageBufAlgo::compare(OIIO::ImageBufAlgo::channels(x, 1, { cx }),
                                         OIIO::ImageBufAlgo::channels(y, 1, { cy }), 0, 0);
    return d.maxerror == 0;
}

}  // namespace

TEST(Pipeline, ASequenceIntoOneFileIsAnError)
{
    std::string dir = mcdn_test::temp_dir("pipeline_pattern");
    make_shot(dir);
    auto run =
        run_mcdntool("-i " + quote(dir + "/shot.#.exr") + " --cnn -o " + quote(dir + "/out.exr"));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("every frame would overwrite it"), std::string::npos) << run.output;
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.exr"));
}

TEST(Pipeline, DenoisingWithoutOutputWarns)
{
    auto run = run_mcdntool("-i " + box("box_0016spp.exr") + " --cnn");
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("warning: no -o"), std::string::npos) << run.output;
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " --info");
    EXPECT_EQ(run.output.find("warning: no -o"), std::string::npos) << run.output;
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " --cnn --metrics " + box("box_ref.exr"));
    EXPECT_EQ(run.output.find("warning: no -o"), std::string::npos) << run.output;
}

// The variance and half files are read only as far as the chain uses them (the faces of
// the roles; no feature halves without NFOR), with the same result as reading them whole.
TEST(Pipeline, OnlyTheChannelsTheChainUsesAreRead)
{
    std::string dir = mcdn_test::temp_dir("pipeline_selection");
    const std::string in = "-i " + box("box_0016spp.exr") + " -i:as=variance "
                           + box("box_0016spp_var.exr") + " -i:as=halfA " + box("box_0016spp_A.exr")
                           + " -i:as=halfB " + box("box_0016spp_B.exr");
    auto info = run_mcdntool(in + " --cnn --info");
    EXPECT_NE(info.output.find("73 channels from 4 input(s)"), std::string::npos) << info.output;
    info = run_mcdntool(in + " --nfor --info");
    EXPECT_NE(info.output.find("141 channels from 4 input(s)"), std::string::npos) << info.output;
    // --info alone reads what any stage could: the halves are found.
    info = run_mcdntool(in + " --info");
    EXPECT_NE(info.output.find("141 channels from 4 input(s)"), std::string::npos) << info.output;
    EXPECT_NE(info.output.find("two-buffer"), std::string::npos) << info.output;
    EXPECT_EQ(info.output.find("no half buffers"), std::string::npos) << info.output;
    int k = 0;
    for (const char* chain : { "--denoise", "--prefilter --nfor --sure --mix" }) {
        const std::string a = dir + "/a" + std::to_string(k) + ".exr";
        const std::string b = dir + "/b" + std::to_string(k++) + ".exr";
        ASSERT_EQ(run_mcdntool(in + " " + chain + " -o " + quote(a)).exit_code, 0);
        // --info:verbose lists every channel, so everything is read.
        ASSERT_EQ(run_mcdntool(in + " --info:verbose " + chain + " -o " + quote(b)).exit_code, 0);
        EXPECT_TRUE(same_channel(a, b, "ViewLayer.Combined.R")) << chain;
        EXPECT_TRUE(same_channel(a, b, "ViewLayer.Combined.B")) << chain;
    }
}

TEST(Pipeline, SkipExistingAndSkipBadFrames)
{
    std::string dir = mcdn_test::temp_dir("pipeline_frames");
    make_shot(dir);
    const std::string shot = "-i " + quote(dir + "/shot.#.exr") + " -i:as=variance "
                             + quote(dir + "/shot_var.#.exr") + " --denoise -o "
                             + quote(dir + "/out.#.exr");
    OIIO::Filesystem::copy(dir + "/shot.0001.exr", dir + "/out.0002.exr");  // "done" already
    auto run = run_mcdntool(shot + " --skip-existing");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("frame 2 ("), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("skipped: its outputs exist"), std::string::npos) << run.output;
    EXPECT_TRUE(same_channel(dir + "/out.0002.exr", dir + "/shot.0001.exr", "ViewLayer.Combined.R"))
        << "an existing output is left alone";
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/out.0003.exr"));

    // A truncated frame 2: without --skip-bad-frames the sequence stops there, with it the
    // other frames are written, the bad one listed, and the exit status says so.
    OIIO::Filesystem::remove(dir + "/out.0001.exr");
    OIIO::Filesystem::remove(dir + "/out.0002.exr");
    OIIO::Filesystem::remove(dir + "/out.0003.exr");
    std::string bytes;
    OIIO::Filesystem::read_text_file(dir + "/shot.0002.exr", bytes);
    std::FILE* f = std::fopen((dir + "/shot.0002.exr").c_str(), "wb");
    std::fwrite(bytes.data(), 1, bytes.size() / 3, f);
    std::fclose(f);
    run = run_mcdntool(shot + " --parallel-frames 1");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.0003.exr")) << run.output;
    for (const char* flag : { " --skip-bad-frames", " --continue" }) {
        OIIO::Filesystem::remove(dir + "/out.0001.exr");
        OIIO::Filesystem::remove(dir + "/out.0003.exr");
        run = run_mcdntool(shot + flag);
        EXPECT_EQ(run.exit_code, 1) << run.output;
        EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/out.0001.exr")) << run.output;
        EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/out.0003.exr")) << run.output;
        EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.0002.exr")) << run.output;
        EXPECT_NE(run.output.find("1 of 3 frames failed: 2"), std::string::npos) << run.output;
    }
}

TEST(Pipeline, ChannelWildcardsSelectWhatIsWritten)
{
    std::string dir = mcdn_test::temp_dir("pipeline_ch");
    auto run = run_mcdntool(
        "-i " + box("box_0016spp.exr") + " -i:as=variance " + box("box_0016spp_var.exr")
        + " --cnn --sure --mix:alpha=1 --ch 'ViewLayer.Combined.*,mix.alpha.*' -o "
        + quote(dir + "/out.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    OIIO::ImageBuf out(dir + "/out.exr");
    EXPECT_EQ(out.spec().nchannels, 7);
    EXPECT_GE(out.spec().channelindex("mix.alpha.G"), 0);
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " --cnn --ch 'nothing.*' -o "
                       + quote(dir + "/x.exr"));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("--ch nothing.*: no channel matches"), std::string::npos)
        << run.output;
}

TEST(Pipeline, ChannelsAStageWasAskedToAddAreWritten)
{
    // mse=1, selection=1, alpha=1 ask for channels: -o writes them beside the render's own,
    // and nothing else a stage made (sure.*, noisy.*).
    std::string dir = mcdn_test::temp_dir("pipeline_maps");
    auto run = run_mcdntool(
        "-i " + box("box_0016spp.exr") + " -i:as=variance " + box("box_0016spp_var.exr")
        + " -i:as=halfA " + box("box_0016spp_A.exr") + " -i:as=halfB " + box("box_0016spp_B.exr")
        + " --nfor:mse=1:selection=1 --sure --mix:alpha=1 -o " + quote(dir + "/out.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const std::string render_path = mcdn_test::test_data("box16/box_0016spp.exr");
    OIIO::ImageBuf out(dir + "/out.exr"), render(render_path);
    ASSERT_TRUE(out.init_spec(dir + "/out.exr", 0, 0)) << out.geterror();
    ASSERT_TRUE(render.init_spec(render_path, 0, 0)) << render.geterror();
    EXPECT_EQ(out.spec().nchannels, render.spec().nchannels + 9);
    for (const char* name : { "nfor.mse.R", "nfor.selection.B", "mix.alpha.G" })
        EXPECT_GE(out.spec().channelindex(name), 0) << name;
    for (const std::string& name : out.spec().channelnames)
        EXPECT_NE(name.rfind("sure.", 0), 0u) << name;
}

TEST(Pipeline, FeaturesAreWrittenBackUnchangedUnlessAsked)
{
    std::string dir = mcdn_test::temp_dir("pipeline_features");
    const std::string in = "-i " + box("box_0016spp.exr") + " -i:as=variance "
                           + box("box_0016spp_var.exr") + " -i:as=halfA " + box("box_0016spp_A.exr")
                           + " -i:as=halfB " + box("box_0016spp_B.exr");
    const std::string render = mcdn_test::test_data("box16/box_0016spp.exr");
    const std::string albedo = "ViewLayer.Denoising Albedo.R";
    int k = 0;  // a new name each run: OIIO's image cache keeps what it read of a name
    for (const char* chain :
         { "--nfor", "--prefilter --nfor", "--prefilter --nfor --sure --mix" }) {
        const std::string out = dir + "/out" + std::to_string(k++) + ".exr";
        auto run = run_mcdntool(in + " " + chain + " -o " + quote(out));
        ASSERT_EQ(run.exit_code, 0) << run.output;
        EXPECT_TRUE(same_channel(out, render, albedo)) << chain;
        EXPECT_FALSE(same_channel(out, render, "ViewLayer.Combined.R")) << chain;
    }
    for (const char* chain : { "--prefilter:features-out=1 --nfor", "--nfor:features-out=1" }) {
        const std::string out = dir + "/out" + std::to_string(k++) + ".exr";
        auto run = run_mcdntool(in + " " + chain + " -o " + quote(out));
        ASSERT_EQ(run.exit_code, 0) << run.output;
        EXPECT_FALSE(same_channel(out, render, albedo)) << chain;
    }
}

TEST(Pipeline, ColorSpaceIsSaidAndNeverGuessed)
{
    std::string dir = mcdn_test::temp_dir("pipeline_color");
    // The file's own tag is printed with -v.
    auto run =
        run_mcdntool("-v -i " + box("box_0016spp.exr") + " --cnn -o " + quote(dir + "/a.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("colour space 'lin_rec709'"), std::string::npos) << run.output;
    // An unknown name is an error naming it and the config.
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " --aov:colorspace=nonesuch --cnn -o "
                       + quote(dir + "/b.exr"));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("'nonesuch'"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("config.ocio"), std::string::npos) << run.output;
    // An unreadable config is an error naming it.
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " --cnn -o " + quote(dir + "/c.exr"),
                       "OCIO=" + dir + "/missing.ocio");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("missing.ocio"), std::string::npos) << run.output;
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/c.exr"));

    // ACEScg by its chromaticities (AP1), no oiio:ColorSpace beyond OIIO's "Linear".
    OIIO::ImageBuf render(mcdn_test::test_data("box16/box_0016spp.exr"));
    render.read(0, 0, true, OIIO::TypeDesc::FLOAT);
    const float ap1[8] = { 0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f };
    render.specmod().attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), ap1);
    ASSERT_TRUE(render.write(dir + "/acescg.exr"));
    run =
        run_mcdntool("-v -i " + quote(dir + "/acescg.exr") + " --cnn -o " + quote(dir + "/d.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("colour space 'acescg' (the file's chromaticities (ACES AP1"),
              std::string::npos)
        << run.output;
    // Other primaries (P3) by their own matrix, not as Rec.709; none that make no primaries.
    const float p3[8] = { 0.680f, 0.320f, 0.265f, 0.690f, 0.150f, 0.060f, 0.3127f, 0.3290f };
    render.specmod().attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), p3);
    ASSERT_TRUE(render.write(dir + "/p3.exr"));
    run = run_mcdntool("-v -i " + quote(dir + "/p3.exr") + " --cnn -o " + quote(dir + "/e.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("colour space 'primaries 0.68,0.32"), std::string::npos)
        << run.output;
    const float flat[8] = { 0.3f, 0.3f, 0.3f, 0.3f, 0.3f, 0.3f, 0.3127f, 0.3290f };
    render.specmod().attribute("chromaticities", OIIO::TypeDesc(OIIO::TypeDesc::FLOAT, 8), flat);
    ASSERT_TRUE(render.write(dir + "/flat.exr"));
    run = run_mcdntool("-i " + quote(dir + "/flat.exr") + " --cnn -o " + quote(dir + "/f.exr"));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("are not three primaries"), std::string::npos) << run.output;
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/f.exr"));
}

TEST(Pipeline, HelpPerCommandAndInfoSayWhatEachStageNeeds)
{
    auto run = run_mcdntool("--help nfor");
    EXPECT_EQ(run.exit_code, 0);
    EXPECT_NE(run.output.find("two half buffers"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("Modifiers"), std::string::npos) << run.output;
    run = run_mcdntool("--help --mix");
    EXPECT_NE(run.output.find("give --sure first"), std::string::npos) << run.output;
    run = run_mcdntool("--help nofr");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("did you mean '--nfor'"), std::string::npos) << run.output;

    run = run_mcdntool("-i " + box("box_0016spp.exr") + " --info");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("--sure       no : needs the colour's variance"), std::string::npos)
        << run.output;
    EXPECT_NE(run.output.find("--denoise    runs cnn:"), std::string::npos) << run.output;
}

TEST(Pipeline, ErrorsNameTheRealFix)
{
    // --nfor on a render alone: render halves, or use a stage that needs none.
    auto run = run_mcdntool("-i " + box("box_0016spp.exr") + " --nfor -o /tmp/mcdn_never.exr");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("render two half buffers"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("--denoise"), std::string::npos) << run.output;
    // --mix without --sure says so.
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " -i:as=variance "
                       + box("box_0016spp_var.exr") + " --cnn --mix -o /tmp/mcdn_never.exr");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("--sure"), std::string::npos) << run.output;
}

TEST(Pipeline, HistoryRecordsTheCommandLine)
{
    std::string dir = mcdn_test::temp_dir("pipeline_history");
    auto run =
        run_mcdntool("-i " + box("box_0016spp.exr") + " --cnn -o " + quote(dir + "/out.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    OIIO::ImageBuf out(dir + "/out.exr");
    const std::string history = out.spec().get_string_attribute("Exif:ImageHistory");
    EXPECT_NE(history.find("\nmcdntool -i "), std::string::npos) << history;
    EXPECT_NE(history.find("--cnn -o"), std::string::npos) << history;
    EXPECT_NE(out.spec().get_string_attribute("Software").find("mcdenoise"), std::string::npos);
}

// Inputs, stages and one -o stream: the chain runs in bands of rows, each written as it is
// made, with the same file as command by command (a --fixnan none between makes it so).
TEST(Pipeline, StagesAndOneOutputStreamInBands)
{
    std::string dir = mcdn_test::temp_dir("pipeline_streamed");
    const std::string in =
        "-i " + box("box_0016spp.exr") + " -i:as=variance " + box("box_0016spp_var.exr");
    int k = 0;
    for (const char* chain : { "--denoise", "--cnn", "--nfor --sure --mix:model=analytic" }) {
        const std::string streamed = dir + "/s" + std::to_string(k) + ".exr";
        const std::string by_command = dir + "/c" + std::to_string(k++) + ".exr";
        // -v and --threads after the stages, as oiiotool takes them: set for the run, the
        // chain still streams (they once made it run command by command, the frame whole).
        auto run = run_mcdntool(in + " " + chain + " -v --threads 2 -o " + quote(streamed),
                                "MCDN_BAND_PIXELS=1024");
        ASSERT_EQ(run.exit_code, 0) << run.output;
        EXPECT_NE(run.output.find("in 2 band(s) of rows"), std::string::npos) << run.output;
        // -v counts the converged tiles of the bands as of the whole frame.
        const auto whole = run_mcdntool(
            "-v " + in + " " + chain + " -o " + quote(dir + "/whole.exr"), "MCDN_BAND_PIXELS=0");
        ASSERT_EQ(whole.exit_code, 0) << whole.output;
        auto converged_line = [](const std::string& out) {
            const size_t at = out.find(" tiles converged");
            if (at == std::string::npos)
                return std::string();
            const size_t begin = out.rfind('\n', at) + 1;  // npos + 1 = 0
            return out.substr(begin, at - begin);
        };
        EXPECT_NE(converged_line(whole.output), "") << whole.output;
        EXPECT_EQ(converged_line(run.output), converged_line(whole.output)) << chain;
        run = run_mcdntool(in + " --fixnan none " + chain + " -v -o " + quote(by_command));
        ASSERT_EQ(run.exit_code, 0) << run.output;
        EXPECT_NE(run.output.find("the stages run command by command"), std::string::npos)
            << run.output;
        OIIO::ImageBuf a(streamed), b(by_command);
        ASSERT_EQ(a.spec().channelnames, b.spec().channelnames) << chain;
        EXPECT_EQ(a.spec().get_string_attribute("Software"),
                  b.spec().get_string_attribute("Software"));
        const auto d = OIIO::ImageBufAlgo::compare(a, b, 0, 0);
        // The stage commands take the light passes into light and back stage by stage, the
        // streamed chain once: last-bit differences there (mcdn/color.h).
        EXPECT_LE(d.maxerror, std::string(chain) == "--denoise" ? 1e-4 : 1e-6) << chain;
    }
    // A chain that fails leaves neither the output nor a temporary.
    auto run = run_mcdntool("-i " + box("box_0016spp.exr") + " --nfor -o " + quote(dir + "/f.exr"));
    EXPECT_EQ(run.exit_code, 1);
    std::vector<std::string> files;
    OIIO::Filesystem::get_directory_entries(dir, files);
    for (const auto& f : files)
        EXPECT_EQ(f.find("f.exr"), std::string::npos) << f;
}

// The safety nets' counts of a streamed chain: -v says the bands' sum; the file's header,
// written before the other bands exist, carries none (one band's would stand for the
// frame's), where a frame of one band carries its own. The variance made a 100th of the
// render's: NFOR's own MSE estimate sends every tile back to the render.
TEST(Pipeline, AStreamedFileCarriesNoOneBandsCounts)
{
    const std::string dir = mcdn_test::temp_dir("pipeline_streamed_counts");
    const std::string variance = dir + "/var.exr";
    auto scale = mcdn_test::run_command("oiiotool " + box("box_0016spp_var.exr") + " --divc 100 -o "
                                        + quote(variance));
    ASSERT_EQ(scale.exit_code, 0) << scale.output;
    const std::string in = "-i " + box("box_0016spp.exr") + " -i:as=variance " + quote(variance)
                           + " -i:as=halfA " + box("box_0016spp_A.exr") + " -i:as=halfB "
                           + box("box_0016spp_B.exr");
    for (const char* bands : { "1024", "0" }) {
        const std::string out = dir + "/out" + bands + ".exr";
        // skip=0: so clean a render's tiles would be converged, and passed through.
        auto run = run_mcdntool(in + " --nfor:skip=0:outliers=off -v -o " + quote(out),
                                std::string("MCDN_BAND_PIXELS=") + bands);
        ASSERT_EQ(run.exit_code, 0) << run.output;
        EXPECT_NE(run.output.find("nfor: "), std::string::npos) << run.output;
        EXPECT_NE(run.output.find(" are the render: NFOR's own MSE estimate"), std::string::npos)
            << run.output;
        const OIIO::ImageBuf written(out);
        EXPECT_EQ(written.spec().get_int_attribute("mcdn:nfor_fallback_count", -1),
                  std::string(bands) == "0" ? 4 : -1)
            << bands;
    }
}

// A streamed chain reads its inputs a band at a time and checks each band's values as it
// reads them: a bad value in a later band still stops the run with the one-line error (file,
// channel, pixel), and neither the output nor a temporary is left.
TEST(Pipeline, StreamedChainChecksEveryBandsValues)
{
    const std::string dir = mcdn_test::temp_dir("pipeline_streamed_bad");
    OIIO::ImageBuf variance(mcdn_test::test_data("box16/box_0016spp_var.exr"));
    ASSERT_TRUE(variance.read(0, 0, true, OIIO::TypeDesc::FLOAT));
    const int r = variance.spec().channelindex("ViewLayer.Combined.R");
    ASSERT_GE(r, 0);
    variance.setpixel(7, 50, std::vector<float>(size_t(variance.nchannels()), -1.0f).data());
    const std::string bad = dir + "/bad_var.exr";
    ASSERT_TRUE(variance.write(bad));
    const std::string out = dir + "/out.exr";
    auto run = run_mcdntool("-i " + box("box_0016spp.exr") + " -i:as=variance " + quote(bad)
                                + " --cnn -o " + quote(out),
                            "MCDN_BAND_PIXELS=1024");
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("bad_var.exr"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("negative variance"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("(7, 50)"), std::string::npos) << run.output;
    // A half buffer's NaN: the light pass does not read the halves, the band that holds it
    // does, with the output already open.
    OIIO::ImageBuf half(mcdn_test::test_data("box16/box_0016spp_A.exr"));
    ASSERT_TRUE(half.read(0, 0, true, OIIO::TypeDesc::FLOAT));
    half.setpixel(9, 60, std::vector<float>(size_t(half.nchannels()), NAN).data());
    const std::string bad_half = dir + "/bad_A.exr";
    ASSERT_TRUE(half.write(bad_half));
    run =
        run_mcdntool("-v -i " + box("box_0016spp.exr") + " -i:as=variance "
                         + box("box_0016spp_var.exr") + " -i:as=halfA " + quote(bad_half)
                         + " -i:as=halfB " + box("box_0016spp_B.exr") + " --nfor -o " + quote(out),
                     "MCDN_BAND_PIXELS=1024");
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("bad_A.exr"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("NaN at pixel (9, 60)"), std::string::npos) << run.output;
    std::vector<std::string> files;
    OIIO::Filesystem::get_directory_entries(dir, files);
    for (const auto& f : files)
        EXPECT_EQ(f.find("out.exr"), std::string::npos) << f;
}

// --nfor:frames=N (cross-frame NFOR, §8): each frame reads its neighbours' files, also
// outside the --frames chunk, and writes only its own output; the inputs stay as they were.
TEST(Pipeline, CrossFrameReadsNeighboursAcrossTheChunkAndWritesNone)
{
    const std::string dir = mcdn_test::temp_dir("pipeline_cross_frame");
    std::map<std::string, std::string> before;
    for (int f : { 1, 2, 3, 4 })
        for (const char* face : { "", "_var", "_A", "_B" }) {
            const std::string src =
                mcdn_test::test_data(std::string("box16/box_0016spp") + face + ".exr");
            const std::string dst =
                OIIO::Strutil::fmt::format("{}/shot{}.{:04d}.exr", dir, face, f);
            if (*face) {
                OIIO::Filesystem::copy(src, dst);
            } else {  // the render with Blender's Vector pass: a still camera
                OIIO::ImageBuf render(src);
                const int n = render.nchannels();
                std::vector<int> order(size_t(n) + 4, -1);
                std::vector<float> values(size_t(n) + 4, 0.0f);
                std::vector<std::string> names(render.spec().channelnames);
                for (int c = 0; c < n; ++c)
                    order[size_t(c)] = c;
                for (const char* c : { "X", "Y", "Z", "W" })
                    names.push_back(std::string("ViewLayer.Vector.") + c);
                OIIO::ImageBuf with =
                    OIIO::ImageBufAlgo::channels(render, n + 4, order, values, names);
                ASSERT_TRUE(with.write(dst)) << with.geterror();
            }
            std::string bytes;
            OIIO::Filesystem::read_text_file(dst, bytes);
            before[dst] = bytes;
        }
    const std::string shot = "-i " + quote(dir + "/shot.#.exr") + " -i:as=variance "
                             + quote(dir + "/shot_var.#.exr") + " -i:as=halfA "
                             + quote(dir + "/shot_A.#.exr") + " -i:as=halfB "
                             + quote(dir + "/shot_B.#.exr");
    auto run = run_mcdntool(shot + " --frames 2-3 --prefilter --nfor:frames=1 -o "
                            + quote(dir + "/out.#.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/out.0002.exr"));
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/out.0003.exr"));
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.0001.exr"));
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.0004.exr"));
    for (const auto& [path, bytes] : before) {
        std::string now;
        OIIO::Filesystem::read_text_file(path, now);
        EXPECT_TRUE(now == bytes) << path << " changed";
    }

    // The CNN's cross-frame mode (its input combined with the neighbours), alone and as
    // --denoise:frames picks it: also only the chunk's own frames written.
    for (const char* stage : { "--cnn:frames=1", "--denoise:frames=1" }) {
        const std::string out = dir + "/" + std::string(stage).substr(2, 3) + ".#.exr";
        run = run_mcdntool(shot + " --frames 3 " + stage + " -o " + quote(out));
        ASSERT_EQ(run.exit_code, 0) << stage << ": " << run.output;
        EXPECT_TRUE(
            OIIO::Filesystem::exists(dir + "/" + std::string(stage).substr(2, 3) + ".0003.exr"));
        EXPECT_FALSE(
            OIIO::Filesystem::exists(dir + "/" + std::string(stage).substr(2, 3) + ".0002.exr"));
    }

    // The shot's first frame has no previous one: fewer, and -v says so.
    run = run_mcdntool(shot + " --frames 1 -v --nfor:frames=2 -o " + quote(dir + "/first.#.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("no frame 0 (-1)"), std::string::npos) << run.output;

    // A plain Blender sequence (no variance, no halves: Cycles writes none): the frames are
    // weighed by their agreement, and -v says so (issue 46, item 5).
    run = run_mcdntool("-i " + quote(dir + "/shot.#.exr") + " --frames 2 -v --denoise:frames=1 -o "
                       + quote(dir + "/plain_seq.#.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/plain_seq.0002.exr"));
    EXPECT_NE(run.output.find("weighed by how well they agree"), std::string::npos) << run.output;

    // Without motion vectors, and with too many frames: one line each, nothing written.
    // (A half file is no render: as the render, its halves are itself.)
    const std::string plain = "-i " + quote(dir + "/shot_A.#.exr") + " -i:as=halfA "
                              + quote(dir + "/shot_A.#.exr") + " -i:as=halfB "
                              + quote(dir + "/shot_A.#.exr");
    run = run_mcdntool(plain + " --frames 2 --nfor:frames=1 -o " + quote(dir + "/plain.#.exr"));
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("motion"), std::string::npos) << run.output;
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/plain.0002.exr"));
    for (const char* stage : { "--nfor:frames=9", "--denoise:frames=9", "--cnn:frames=x" }) {
        run = run_mcdntool(shot + " --frames 2 " + stage + " -o " + quote(dir + "/nine.#.exr"));
        EXPECT_NE(run.exit_code, 0);
        EXPECT_NE(run.output.find(std::string(stage).substr(std::string(stage).find(':') + 1)),
                  std::string::npos)
            << run.output;
    }
}

// A file of two Blender view layers (BG, and FG with other pixels): --denoise with no other
// flag denoises both, each exactly as --aov:layer=NAME alone does, and -v names each
// (issue 46, item 1; before, FG came out as it went in).
TEST(Pipeline, EveryViewLayerIsDenoised)
{
    std::string dir = mcdn_test::temp_dir("pipeline_layers");
    for (const char* face : { "", "_var" }) {
        OIIO::ImageBuf bg(mcdn_test::test_data(std::string("box16/box_0016spp") + face + ".exr"));
        ASSERT_TRUE(bg.read(0, 0, true, OIIO::TypeFloat));
        OIIO::ImageBuf fg = OIIO::ImageBufAlgo::flip(bg);  // other pixels, same statistics
        OIIO::ImageBuf both = OIIO::ImageBufAlgo::channel_append(bg, fg);
        std::vector<std::string> names;
        for (int layer = 0; layer < 2; ++layer)
            for (const auto& name : bg.spec().channelnames)
                names.push_back(OIIO::Strutil::replace(name, "ViewLayer.", layer ? "FG." : "BG."));
        both.specmod().channelnames = names;
        ASSERT_TRUE(both.write(dir + "/layers" + face + ".exr"));
    }
    const std::string in =
        "-i " + quote(dir + "/layers.exr") + " -i:as=variance " + quote(dir + "/layers_var.exr");
    auto run = run_mcdntool("-v " + in + " --denoise -o " + quote(dir + "/all.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("view layer 'BG' (1 of 2)"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("view layer 'FG' (2 of 2)"), std::string::npos) << run.output;
    OIIO::ImageBuf input(dir + "/layers.exr"), all(dir + "/all.exr");
    for (const char* layer : { "BG", "FG" }) {
        run = run_mcdntool(in + " --aov:layer=" + layer + " --denoise -o "
                           + quote(dir + "/" + layer + ".exr"));
        ASSERT_EQ(run.exit_code, 0) << run.output;
        OIIO::ImageBuf alone(dir + "/" + layer + ".exr");
        const std::string red = std::string(layer) + ".Combined.R";
        const int c = all.spec().channelindex(red);
        ASSERT_GE(c, 0);
        const OIIO::ROI channel(0, 64, 0, 64, 0, 1, c, c + 1);
        EXPECT_EQ(OIIO::ImageBufAlgo::compare(all, alone, 0, 0, channel).maxerror, 0.0) << layer;
        EXPECT_GT(OIIO::ImageBufAlgo::compare(all, input, 0, 0, channel).maxerror, 0.01) << layer;
    }
}

// Blender's File Output node (multilayer) names its channels by its sockets: Image.R,
// Denoising Albedo.R, Denoising Depth.V, no view layer. Read as the cycles preset, denoised
// exactly as the view layer's names are (issue 46, item 2; before, --info and --denoise
// failed with "role 'color' not found").
TEST(Pipeline, BlendersFileOutputNamesAreTheCyclesPreset)
{
    std::string dir = mcdn_test::temp_dir("pipeline_file_output");
    for (const char* face : { "", "_var" }) {
        OIIO::ImageBuf in(mcdn_test::test_data(std::string("box16/box_0016spp") + face + ".exr"));
        ASSERT_TRUE(in.read(0, 0, true, OIIO::TypeFloat));
        std::vector<std::string> names;
        for (std::string name : in.spec().channelnames) {
            name = OIIO::Strutil::replace(name, "ViewLayer.", "");
            name = OIIO::Strutil::replace(name, "Combined.", "Image.");
            name = OIIO::Strutil::replace(name, "Depth.Z", "Depth.V");
            names.push_back(name);
        }
        in.specmod().channelnames = names;
        ASSERT_TRUE(in.write(dir + "/fo" + face + ".exr"));
    }
    auto run = run_mcdntool("-i " + quote(dir + "/fo.exr") + " --info");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("AOV preset 'cycles'"), std::string::npos) << run.output;
    run = run_mcdntool("-v -i " + quote(dir + "/fo.exr") + " -i:as=variance "
                       + quote(dir + "/fo_var.exr") + " --denoise -o " + quote(dir + "/out.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("File Output node names"), std::string::npos) << run.output;
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " -i:as=variance "
                       + box("box_0016spp_var.exr") + " --denoise -o " + quote(dir + "/vl.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    OIIO::ImageBuf fo(dir + "/out.exr"), vl(dir + "/vl.exr");
    for (const char* c : { "R", "G", "B" }) {
        const int a = fo.spec().channelindex(std::string("Image.") + c);
        const int b = vl.spec().channelindex(std::string("ViewLayer.Combined.") + c);
        ASSERT_GE(a, 0);
        ASSERT_GE(b, 0);
        OIIO::ImageBuf fa = OIIO::ImageBufAlgo::channels(fo, 1, { a });
        OIIO::ImageBuf vb = OIIO::ImageBufAlgo::channels(vl, 1, { b });
        EXPECT_EQ(OIIO::ImageBufAlgo::compare(fa, vb, 0, 0).maxerror, 0.0) << c;
    }
}

// Blender writes no variance: K renders with different seeds, given as -i:as=seed, are read
// as their mean with its variance and halves, so that every chain runs on a plain Cycles
// render. The box's two halves are two such seeds (8 samples each).
TEST(Pipeline, SeedRendersGiveTheVarianceAndHalvesBlenderDoesNotWrite)
{
    std::string dir = mcdn_test::temp_dir("pipeline_seeds");
    const std::string seeds =
        "-i:as=seed " + box("box_0016spp_A.exr") + " -i:as=seed " + box("box_0016spp_B.exr");
    auto run = run_mcdntool(seeds + " --info");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("variance"), std::string::npos) << run.output;
    for (const char* stage : { "--nfor", "--denoise", "--cnn --sure --mix" }) {
        run = run_mcdntool(seeds + " " + stage + " -o " + quote(dir + "/out.exr"));
        ASSERT_EQ(run.exit_code, 0) << stage << ": " << run.output;
    }
    // Without a stage the output is the seeds' mean: the render the halves came from, in the
    // render's own channels (no variance or half channel), each of its type.
    run = run_mcdntool(seeds + " -o " + quote(dir + "/mean.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    OIIO::ImageBuf mean(dir + "/mean.exr"), render(mcdn_test::test_data("box16/box_0016spp.exr"));
    ASSERT_TRUE(mean.read(0, 0, true, OIIO::TypeFloat) && render.read(0, 0, true, OIIO::TypeFloat));
    EXPECT_EQ(mean.spec().channelnames, render.spec().channelnames);
    const int r = render.spec().channelindex("ViewLayer.Combined.R");
    OIIO::ImageBuf mr = OIIO::ImageBufAlgo::channels(mean, 1, { r });
    OIIO::ImageBuf rr = OIIO::ImageBufAlgo::channels(render, 1, { r });
    EXPECT_LT(OIIO::ImageBufAlgo::compare(mr, rr, 1e-3f, 1e-3f).maxerror, 1e-3);
    // One seed gives no variance; seeds of different passes are not one frame's.
    run = run_mcdntool("-i:as=seed " + box("box_0016spp_A.exr") + " --denoise -o "
                       + quote(dir + "/one.exr"));
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("two or more"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("box_0016spp_A.exr"), std::string::npos) << run.output;
    OIIO::ImageBuf other(mcdn_test::test_data("box16/box_0016spp_B.exr"));
    ASSERT_TRUE(other.read(0, 0, true, OIIO::TypeFloat));
    other.specmod().channelnames[3] = "ViewLayer.Shadow.R";
    ASSERT_TRUE(other.write(dir + "/other.exr"));
    run = run_mcdntool("-i:as=seed " + box("box_0016spp_A.exr") + " -i:as=seed "
                       + quote(dir + "/other.exr") + " --denoise -o " + quote(dir + "/two.exr"));
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("other.exr: channel "), std::string::npos) << run.output;
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/one.exr"));
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/two.exr"));
}

// A farm's log is no terminal: with -v a long stage still says how far it is, a line at a
// time (every $MCDN_LOG_PROGRESS_SECONDS), never the terminal's rewritten line.
TEST(Pipeline, ProgressLinesGoToLogsToo)
{
    std::string dir = mcdn_test::temp_dir("pipeline_log_progress");
    // 512x512: the CNN's tiles report progress.
    OIIO::ImageBuf big =
        OIIO::ImageBufAlgo::resize(OIIO::ImageBuf(mcdn_test::test_data("box16/box_0016spp.exr")),
                                   "", 0.0f, OIIO::ROI(0, 512, 0, 512));
    ASSERT_TRUE(big.write(dir + "/big.exr"));
    const std::string args = "-i " + quote(dir + "/big.exr") + " --cnn -o " + quote(dir + "/o.exr");
    auto run = run_mcdntool("-v " + args, "MCDN_LOG_PROGRESS_SECONDS=0");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("mcdntool: cnn "), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("%\n"), std::string::npos) << run.output;
    EXPECT_EQ(run.output.find('\r'), std::string::npos) << run.output;
    // Without -v, a log holds no progress.
    run = run_mcdntool(args, "MCDN_LOG_PROGRESS_SECONDS=0");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_EQ(run.output.find('%'), std::string::npos) << run.output;
}

// -v's header (colour space, preset, features) once for a sequence, not once per frame.
TEST(Pipeline, VerboseHeaderIsSaidOncePerRun)
{
    std::string dir = mcdn_test::temp_dir("pipeline_header_once");
    for (int f = 1; f <= 3; ++f)
        OIIO::Filesystem::copy(mcdn_test::test_data("box16/box_0016spp.exr"),
                               dir + "/s.000" + std::to_string(f) + ".exr");
    auto run =
        run_mcdntool("-v -i " + quote(dir + "/s.#.exr") + " --cnn -o " + quote(dir + "/o.#.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    auto count = [&](const std::string& what) {
        size_t n = 0;
        for (size_t at = run.output.find(what); at != std::string::npos;
             at = run.output.find(what, at + 1))
            ++n;
        return n;
    };
    EXPECT_EQ(count("AOV preset 'cycles'"), 1u) << run.output;
    EXPECT_EQ(count("features found"), 1u) << run.output;
    EXPECT_EQ(count("colour space '"), 1u) << run.output;
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/o.0003.exr"));
}

// An 8-bit sRGB PNG (what a web or review render is): linearised through OCIO, denoised,
// encoded back and written as the 8-bit PNG it came as. Measured in linear against the
// reference: 0.155 as given, 0.030 denoised.
TEST(Pipeline, LdrPngIsLinearisedDenoisedAndEncodedBack)
{
    std::string dir = mcdn_test::temp_dir("pipeline_png");
    OIIO::ImageBuf render(mcdn_test::test_data("box16/box_0016spp.exr"));
    const int r = render.spec().channelindex("ViewLayer.Combined.R");
    OIIO::ImageBuf rgb =
        OIIO::ImageBufAlgo::channels(render, 3, { r, r + 1, r + 2 }, {}, { "R", "G", "B" });
    OIIO::ImageBuf srgb = OIIO::ImageBufAlgo::colorconvert(rgb, "linear", "sRGB");
    ASSERT_TRUE(srgb.write(dir + "/in.png", OIIO::TypeDesc::UINT8)) << srgb.geterror();
    auto run =
        run_mcdntool("-i " + quote(dir + "/in.png") + " --denoise -o " + quote(dir + "/out.png"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    OIIO::ImageBuf out(dir + "/out.png"), in(dir + "/in.png");
    ASSERT_TRUE(out.init_spec(dir + "/out.png", 0, 0));
    EXPECT_EQ(out.spec().format, OIIO::TypeDesc::UINT8);
    EXPECT_EQ(out.spec().nchannels, 3);
    auto linear_relmse = [&](OIIO::ImageBuf& encoded, const std::string& name) {
        OIIO::ImageBuf lin = OIIO::ImageBufAlgo::colorconvert(encoded, "sRGB", "linear");
        EXPECT_TRUE(lin.write(dir + "/" + name + ".exr", OIIO::TypeDesc::FLOAT));
        auto m = run_mcdntool("-i " + quote(dir + "/" + name + ".exr")
                              + " --aov:preset=generic --metrics " + box("box_ref.exr"));
        const size_t at = m.output.find("relMSE ");
        EXPECT_NE(at, std::string::npos) << m.output;
        return at == std::string::npos ? 0.0 : std::stod(m.output.substr(at + 7));
    };
    const double before = linear_relmse(in, "in"), after = linear_relmse(out, "out");
    EXPECT_LT(after, 0.5 * before) << before << " -> " << after;
}
