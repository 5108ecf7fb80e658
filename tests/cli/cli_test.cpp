// The built mcdntool end to end: commands, errors, sequences, and that inputs stay intact.
#include <fstream>
#include <regex>

#include "command_line.h"
#include "mcdn_test.h"

using mcdn_test::quote;
using mcdn_test::run_mcdntool;

namespace {

std::string box(const std::string& name)
{
    return quote(mcdn_test::test_data("box16/" + name));
}

std::string box_inputs()
{
    return "-i " + box("box_0016spp.exr") + " -i:as=variance " + box("box_0016spp_var.exr")
           + " -i:as=halfA " + box("box_0016spp_A.exr") + " -i:as=halfB " + box("box_0016spp_B.exr")
           + " --aov:preset=cycles";
}

double json_number(const std::string& text, const std::string& key)
{
    std::smatch m;
    std::regex pattern("\"" + key + "\": ([-0-9.eE+]+)");
    if (!std::regex_search(text, m, pattern))
        return NAN;
    return std::stod(m[1]);
}

std::string file_bytes(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), {});
}

std::vector<std::string> files_in(const std::string& dir)
{
    std::vector<std::string> files;
    OIIO::Filesystem::get_directory_entries(dir, files);
    return files;
}

bool one_line(const std::string& s)
{
    return !s.empty() && s.find('\n') == s.size() - 1;
}

}  // namespace

TEST(Cli, HelpListsEveryCommand)
{
    auto run = run_mcdntool("--help");
    EXPECT_EQ(run.exit_code, 0);
    for (const char* cmd : { "-i", "-o", "--aov", "--metrics", "--heatmap", "--info", "--ch",
                             "--threads", "--frames" })
        EXPECT_NE(run.output.find(cmd), std::string::npos) << cmd;
}

TEST(Cli, MetricsJsonOnTheFixture)
{
    auto run = run_mcdntool(box_inputs() + " --metrics:format=json " + box("box_ref.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    double relmse = json_number(run.output, "relmse");
    EXPECT_GT(relmse, 0.01);
    EXPECT_LT(relmse, 1.0);
    EXPECT_GT(json_number(run.output, "ssim"), 0.0);
}

TEST(Cli, TungstenDirectoryMetrics)
{
    std::string dir = mcdn_test::test_data("cornell20");
    auto run = run_mcdntool("-i " + quote(dir) + " --aov:preset=tungsten --metrics:format=json "
                            + quote(dir + "/ref.pfm"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_GT(json_number(run.output, "relmse"), 0.0);
}

TEST(Cli, OutputKeepsTheRenderChannelsAndInputsStayIntact)
{
    std::string dir = mcdn_test::temp_dir("cli_out");
    std::string before = file_bytes(mcdn_test::test_data("box16/box_0016spp.exr"));
    auto run =
        run_mcdntool(box_inputs() + " --info -o:datatype=half " + quote(dir + "/out.exr")
                     + " --heatmap:ref=" + box("box_ref.exr") + " " + quote(dir + "/err.png"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("color_variance"), std::string::npos) << run.output;
    EXPECT_EQ(file_bytes(mcdn_test::test_data("box16/box_0016spp.exr")), before);
    OIIO::ImageBuf out(dir + "/out.exr");
    ASSERT_TRUE(out.init_spec(dir + "/out.exr", 0, 0));
    EXPECT_EQ(out.spec().nchannels, 39);
    EXPECT_EQ(out.spec().format, OIIO::TypeDesc::HALF);
    OIIO::ImageBuf png(dir + "/err.png");
    ASSERT_TRUE(png.init_spec(dir + "/err.png", 0, 0));
    EXPECT_EQ(png.spec().width, 64);
    EXPECT_EQ(files_in(dir).size(), 2u);
}

TEST(Cli, ChannelSelectionForOutput)
{
    std::string dir = mcdn_test::temp_dir("cli_ch");
    auto run = run_mcdntool(box_inputs()
                            + " --ch ViewLayer.Combined.R,ViewLayer.Combined.G,"
                              "ViewLayer.Combined.B -o "
                            + quote(dir + "/rgb.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    OIIO::ImageBuf out(dir + "/rgb.exr");
    ASSERT_TRUE(out.init_spec(dir + "/rgb.exr", 0, 0));
    EXPECT_EQ(out.spec().nchannels, 3);
}

TEST(Cli, UnknownCommandsAndModifiersSuggestTheRightOne)
{
    auto run = run_mcdntool("--metrcs ref.exr");
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("did you mean '--metrics'"), std::string::npos) << run.output;
    EXPECT_TRUE(one_line(run.output)) << run.output;
    run = run_mcdntool("-i:ass=variance x.exr");
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("did you mean ':as'"), std::string::npos) << run.output;
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " --metrics");
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("--metrics needs 1 argument"), std::string::npos) << run.output;
    run = run_mcdntool("-i:as=varience " + box("box_0016spp.exr") + " --info");
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("is not one of mean, variance"), std::string::npos) << run.output;
}

// Values that would abort a naive parser (std::stoull, printf of a '%' in a file name) or reach the
// ops as NaN fail in the parser, before any file is read.
TEST(Cli, BadModifierValuesFailInTheParser)
{
    auto parse = [](const std::string& text, std::string& error) {
        std::vector<std::string> words = OIIO::Strutil::splits(text, " ");
        std::vector<const char*> argv = { "mcdntool" };
        for (const auto& w : words)
            argv.push_back(w.c_str());
        mcdntool::CommandLine line;
        return mcdntool::parse_command_line(int(argv.size()), argv.data(), line, error);
    };
    std::string error;
    EXPECT_TRUE(parse("x.exr --aov:preset=generic --threads 2 color=R,G,B --nfor:k=0.5,1 "
                      "--sure:seed=7:eps=1e-3 --mix --frames 1-3 -o:datatype=half o.exr",
                      error))
        << error;
    for (const char* bad :
         { "--sure:seed=abc", "--sure:seed=-1", "--sure:probes=0", "--sure:eps=nan",
           "--nfor:k=inf,1", "--nfor:k=", "--cnn:tile=x", "--prefilter:k=1e39",
           "--heatmap:min=abc h.png", "-o:datatype=doubel o.exr", "--threads many",
           "--parallel-frames 0", "--frames 1-2000000000", "--frames x", "--aov color=R,G",
           "--nfor:mse=yes", "--nfor:window=4", "--mix:model=neural" }) {
        error.clear();
        EXPECT_FALSE(parse(std::string("x.exr ") + bad, error)) << bad;
        EXPECT_FALSE(error.empty()) << bad;
    }
    std::string normalized, framespec;
    EXPECT_FALSE(mcdntool::is_sequence("x%s.#.exr", normalized, framespec));
    EXPECT_FALSE(mcdntool::is_sequence("x.%088888888884d.exr", normalized, framespec));  // fuzzer
    EXPECT_TRUE(mcdntool::is_sequence("x.%04d.exr", normalized, framespec));
    EXPECT_TRUE(mcdntool::is_sequence("x.1-3#.exr", normalized, framespec));
    EXPECT_EQ(mcdntool::frame_name(normalized, 2), "x.0002.exr");
    EXPECT_EQ(framespec, "1-3");
}

TEST(Cli, BadModifierValueIsOneLineBeforeAnythingRuns)
{
    auto run =
        run_mcdntool("-i " + box("box_0016spp.exr") + " --prefilter --sure:seed=abc -o never.exr");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("--sure:seed=abc is not a whole number"), std::string::npos)
        << run.output;
    EXPECT_TRUE(one_line(run.output)) << run.output;
    // A '%' besides the frame number: the name is taken literally, not as a printf format.
    run = run_mcdntool("-i " + quote(mcdn_test::temp_dir("cli_percent") + "/x%s.#.exr")
                       + " -o o.exr");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("x%s.#.exr"), std::string::npos) << run.output;
    EXPECT_TRUE(one_line(run.output)) << run.output;
}

TEST(Cli, BadInputsFailWithOneLineAndNoOutputFile)
{
    std::string dir = mcdn_test::temp_dir("cli_bad");
    std::string out = quote(dir + "/out.exr");

    // missing channel: the variance role is required by nothing yet, so ask for a bad override
    auto run = run_mcdntool("-i " + box("box_0016spp.exr") + " --aov albedo=X.R,X.G,X.B -o " + out);
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("X.R"), std::string::npos) << run.output;
    EXPECT_TRUE(one_line(run.output)) << run.output;

    // truncated EXR
    std::string bytes = file_bytes(mcdn_test::test_data("box16/box_0016spp.exr"));
    std::ofstream(dir + "/cut.exr", std::ios::binary).write(bytes.data(), bytes.size() / 3);
    run = run_mcdntool("-i " + quote(dir + "/cut.exr") + " -o " + out);
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("cut.exr"), std::string::npos) << run.output;
    EXPECT_TRUE(one_line(run.output)) << run.output;

    // mismatched sizes
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " -i:as=variance "
                       + quote(mcdn_test::test_data("../../examples/box/box_0016spp_var.exr"))
                       + " -o " + out);
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("box_0016spp_var.exr: data window 128x128"), std::string::npos)
        << run.output;

    // NaN pixel in the colour
    OIIO::ImageBuf nan(mcdn_test::test_data("box16/box_0016spp.exr"));
    nan.read(0, 0, true, OIIO::TypeDesc::FLOAT);
    float px[39];
    nan.getpixel(3, 4, px, 39);
    px[2] = NAN;
    nan.setpixel(3, 4, px, 39);
    ASSERT_TRUE(nan.write(dir + "/nan.exr"));
    run = run_mcdntool("-i " + quote(dir + "/nan.exr") + " -o " + out);
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("nan.exr (-i:as=mean): channel 'ViewLayer.Combined.B' (role color) "
                              "has NaN at pixel (3, 4)"),
              std::string::npos)
        << run.output;

    // unreadable path
    run = run_mcdntool("-i " + quote(dir + "/does_not_exist.exr") + " -o " + out);
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("does_not_exist.exr: no such file"), std::string::npos) << run.output;

    // unwritable output (a file where its folder would be): nothing left behind
    run = run_mcdntool("-i " + box("box_0016spp.exr") + " -o " + quote(dir + "/nan.exr/out.exr"));
    EXPECT_NE(run.exit_code, 0);

    auto files = files_in(dir);
    EXPECT_EQ(files.size(), 2u);  // cut.exr and nan.exr, no out.exr, no temporaries
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.exr"));
}

TEST(Cli, FrameSequencesRunOncePerFrame)
{
    std::string dir = mcdn_test::temp_dir("cli_frames");
    for (int f : { 1, 2, 3 })
        for (const char* face : { "", "_var", "_A", "_B" }) {
            std::string src =
                mcdn_test::test_data(std::string("box16/box_0016spp") + face + ".exr");
            OIIO::Filesystem::copy(
                src, OIIO::Strutil::fmt::format("{}/shot{}.{:04d}.exr", dir, face, f));
        }
    auto run =
        run_mcdntool("-i " + quote(dir + "/shot.#.exr") + " -i:as=variance "
                     + quote(dir + "/shot_var.%04d.exr") + " -o " + quote(dir + "/out.@@@@.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("frame 3 (3/3)"), std::string::npos) << run.output;
    for (int f : { 1, 2, 3 })
        EXPECT_TRUE(
            OIIO::Filesystem::exists(OIIO::Strutil::fmt::format("{}/out.{:04d}.exr", dir, f)));

    run = run_mcdntool("-i " + quote(dir + "/shot.#.exr") + " --frames 2-3 -o "
                       + quote(dir + "/only.#.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/only.0001.exr"));
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/only.0003.exr"));

    run =
        run_mcdntool("-i " + quote(dir + "/shot.#.exr") + " -i:as=variance "
                     + quote(dir + "/shot_var.#.exr") + " -i:as=halfA "
                     + quote(dir + "/shot_A.#.exr") + " -i:as=halfB " + quote(dir + "/shot_B.#.exr")
                     + " --parallel-frames 2 --nfor -o " + quote(dir + "/par.#.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    for (int f : { 1, 2, 3 })
        EXPECT_TRUE(
            OIIO::Filesystem::exists(OIIO::Strutil::fmt::format("{}/par.{:04d}.exr", dir, f)));

    run = run_mcdntool("-i " + quote(dir + "/shot.#.exr") + " --frames 1-4 -o "
                       + quote(dir + "/x.#.exr"));
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("frame 4 (4/4): "), std::string::npos) << run.output;
}

TEST(Cli, DoneWhenCommandOnTheSharedBoxPrintsThePublishedRelMse)
{
    MCDN_REQUIRE_SHARED(dir, "box");
    auto f = [&](const std::string& n) { return quote(dir + "/" + n); };
    auto run = run_mcdntool("-i " + f("box_0016spp.exr") + " -i:as=variance "
                            + f("box_0016spp_var.exr") + " -i:as=halfA " + f("box_0016spp_A.exr")
                            + " -i:as=halfB " + f("box_0016spp_B.exr")
                            + " --aov:preset=cycles --metrics:format=json " + f("box_ref.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NEAR(json_number(run.output, "relmse"), 0.1404, 0.0005);

    MCDN_REQUIRE_SHARED(tungsten, "tungsten/cornell20");
    run = run_mcdntool("-i " + quote(tungsten) + " --aov:preset=tungsten --metrics:format=json "
                       + quote(tungsten + "/ref.pfm"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NEAR(json_number(run.output, "relmse"), 0.01185, 0.0005);
}

TEST(Cli, DenoisingChainsRunEndToEnd)
{
    std::string dir = mcdn_test::temp_dir("cli_chains");
    for (const std::string chain :
         { "--prefilter --nfor", "--nfor --sure --mix", "--cnn", "--cnn --sure --mix:alpha=1" }) {
        auto noisy = run_mcdntool(box_inputs() + " --metrics:format=json " + box("box_ref.exr"));
        auto run = run_mcdntool(box_inputs() + " " + chain + " --metrics:format=json "
                                + box("box_ref.exr") + " -o " + quote(dir + "/out.exr"));
        ASSERT_EQ(run.exit_code, 0) << chain << ": " << run.output;
        EXPECT_LT(json_number(run.output, "relmse"), 0.5 * json_number(noisy.output, "relmse"))
            << chain;
    }
}
