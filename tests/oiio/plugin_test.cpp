// The oiiotool format plugin, through Debian's real oiiotool: URI and recipe file, chains,
// and errors that surface as oiiotool errors.
#include <fstream>
#include <regex>

#include "mcdn_test.h"

using mcdn_test::quote;

namespace {

mcdn_test::Run oiiotool(const std::string& args)
{
    return mcdn_test::run_oiiotool(args);
}

std::string box_query(const std::string& chain)
{
    std::string d = mcdn_test::test_data("box16/");
    return "shot.mcdn?in=" + d + "box_0016spp.exr&variance=" + d + "box_0016spp_var.exr&halfA=" + d
           + "box_0016spp_A.exr&halfB=" + d + "box_0016spp_B.exr&preset=cycles&chain=" + chain;
}

double relmse_of(const std::string& image)
{
    auto run = mcdn_test::run_mcdntool("-i " + quote(image)
                                       + " --aov:preset=generic --metrics:format=json "
                                       + quote(mcdn_test::test_data("box16/box_ref.exr")));
    std::smatch m;
    if (!std::regex_search(run.output, m, std::regex("\"relmse\": ([-0-9.eE+]+)")))
        return NAN;
    return std::stod(m[1]);
}

/// The render's colour alone as R,G,B (what relmse_of reads) in `dir`: the error to beat.
std::string noisy_rgb(const std::string& dir)
{
    const std::string noisy = dir + "/noisy.exr";
    auto copy =
        oiiotool(quote(mcdn_test::test_data("box16/box_0016spp.exr"))
                 + " --ch R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,B=ViewLayer.Combined.B -o "
                 + quote(noisy));
    EXPECT_EQ(copy.exit_code, 0) << copy.output;
    return noisy;
}

}  // namespace

TEST(OiioPlugin, QueryRunsTheChainInsideOiiotool)
{
    if (system("command -v oiiotool > /dev/null") != 0)
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = mcdn_test::temp_dir("plugin_query");
    std::string out = dir + "/denoised.exr";
    auto run =
        oiiotool(quote(box_query("prefilter,nfor"))
                 + " --ch R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,B=ViewLayer.Combined.B"
                   " --colorconvert lin_rec709 lin_rec709 -o "
                 + quote(out));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const std::string noisy = noisy_rgb(dir);
    EXPECT_LT(relmse_of(out), 0.5 * relmse_of(noisy));
}

// The plugin streams its inputs in bands as mcdntool does (a frame's inputs are never in
// memory whole): the same image as mcdntool's chain on the whole frame.
TEST(OiioPlugin, BandsOfRowsGiveTheWholeFramesResult)
{
    if (system("command -v oiiotool > /dev/null") != 0)
        GTEST_SKIP() << "oiiotool not installed";
    const std::string dir = mcdn_test::temp_dir("plugin_bands");
    const std::string d = mcdn_test::test_data("box16/box_0016spp");
    auto banded = mcdn_test::run_oiiotool(
        quote(box_query("prefilter,nfor")) + " -o " + quote(dir + "/banded.exr"),
        "MCDN_BAND_PIXELS=1024");  // 16 rows of 64 a band, 4 bands and their halos
    ASSERT_EQ(banded.exit_code, 0) << banded.output;
    auto whole = mcdn_test::run_mcdntool(
        "-i:as=mean " + quote(d + ".exr") + " -i:as=variance " + quote(d + "_var.exr")
            + " -i:as=halfA " + quote(d + "_A.exr") + " -i:as=halfB " + quote(d + "_B.exr")
            + " --aov:preset=cycles" + " --prefilter --nfor -o " + quote(dir + "/whole.exr"),
        "MCDN_BAND_PIXELS=0");
    ASSERT_EQ(whole.exit_code, 0) << whole.output;
    auto diff = mcdn_test::run_command("oiiotool " + quote(dir + "/banded.exr") + " "
                                       + quote(dir + "/whole.exr") + " --diff --fail 0 --warn 0");
    EXPECT_EQ(diff.exit_code, 0) << diff.output;
    EXPECT_NE(diff.output.find("PASS"), std::string::npos) << diff.output;
}

// A half render gives a half image, as oiiotool keeps a half file half and mcdntool writes
// it: the same file as mcdntool's.
TEST(OiioPlugin, AHalfRenderGivesAHalfImage)
{
    if (system("command -v oiiotool > /dev/null") != 0)
        GTEST_SKIP() << "oiiotool not installed";
    const std::string dir = mcdn_test::temp_dir("plugin_half");
    const std::string half = dir + "/half.exr";
    auto convert =
        mcdn_test::run_command("oiiotool " + quote(mcdn_test::test_data("box16/box_0016spp.exr"))
                               + " -d half -o " + quote(half));
    ASSERT_EQ(convert.exit_code, 0) << convert.output;
    const std::string variance = mcdn_test::test_data("box16/box_0016spp_var.exr");
    auto plugin = oiiotool(quote("shot.mcdn?in=" + half + "&variance=" + variance
                                 + "&preset=cycles&chain=prefilter,nfor")
                           + " -o " + quote(dir + "/plugin.exr"));
    ASSERT_EQ(plugin.exit_code, 0) << plugin.output;
    auto tool = mcdn_test::run_mcdntool(
        "-i:as=mean " + quote(half) + " -i:as=variance " + quote(variance)
        + " --aov:preset=cycles --prefilter --nfor -o " + quote(dir + "/tool.exr"));
    ASSERT_EQ(tool.exit_code, 0) << tool.output;
    auto info = mcdn_test::run_command("oiiotool --info " + quote(dir + "/plugin.exr"));
    EXPECT_NE(info.output.find("39 channel, half openexr"), std::string::npos) << info.output;
    auto diff = mcdn_test::run_command("oiiotool " + quote(dir + "/plugin.exr") + " "
                                       + quote(dir + "/tool.exr") + " --diff --fail 0 --warn 0");
    EXPECT_NE(diff.output.find("PASS"), std::string::npos) << diff.output;
}

TEST(OiioPlugin, RecipeFileWithRelativePaths)
{
    if (system("command -v oiiotool > /dev/null") != 0)
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = mcdn_test::temp_dir("plugin_recipe");
    for (const char* f :
         { "box_0016spp.exr", "box_0016spp_var.exr", "box_0016spp_A.exr", "box_0016spp_B.exr" })
        OIIO::Filesystem::copy(mcdn_test::test_data(std::string("box16/") + f), dir + "/" + f);
    std::ofstream(dir + "/shot.mcdn")
        << "# denoise the box\n"
           "in = box_0016spp.exr\nvariance = box_0016spp_var.exr\n"
           "halfA = box_0016spp_A.exr\nhalfB = box_0016spp_B.exr\n"
           "chain = prefilter,nfor,sure,mix\nsure.probes = 1\n"
           "channels = ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B\n";
    auto run = oiiotool(quote(dir + "/shot.mcdn") + " -o " + quote(dir + "/out.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    OIIO::ImageBuf out(dir + "/out.exr");
    ASSERT_TRUE(out.init_spec(dir + "/out.exr", 0, 0)) << out.geterror();
    EXPECT_EQ(out.spec().width, 64);
    EXPECT_EQ(out.spec().nchannels, 3);
}

// seeds = A,B: renders with different seeds, read with their variance and halves (the
// box's two halves are two 8-sample seeds); NFOR runs on them, closer than the render.
TEST(OiioPlugin, RecipeSeedsAreOneRenderWithItsVariance)
{
    if (system("command -v oiiotool > /dev/null") != 0)
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = mcdn_test::temp_dir("plugin_seeds");
    for (const char* f : { "box_0016spp_A.exr", "box_0016spp_B.exr" })
        OIIO::Filesystem::copy(mcdn_test::test_data(std::string("box16/") + f), dir + "/" + f);
    std::ofstream(dir + "/shot.mcdn")
        << "seeds = box_0016spp_A.exr, box_0016spp_B.exr\nchain = prefilter,nfor\n"
           "channels = ViewLayer.Combined.R,ViewLayer.Combined.G,ViewLayer.Combined.B\n";
    auto run = oiiotool(quote(dir + "/shot.mcdn")
                        + " --ch R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,"
                          "B=ViewLayer.Combined.B -o "
                        + quote(dir + "/out.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    const std::string noisy = noisy_rgb(dir);
    EXPECT_LT(relmse_of(dir + "/out.exr"), 0.5 * relmse_of(noisy));
    // in and seeds together: which is the render?
    std::ofstream(dir + "/both.mcdn") << "in = box_0016spp_A.exr\nseeds = box_0016spp_A.exr\n";
    run = oiiotool(quote(dir + "/both.mcdn") + " -o " + quote(dir + "/both.exr"));
    EXPECT_NE(run.exit_code, 0);
    EXPECT_NE(run.output.find("not both"), std::string::npos) << run.output;
}

TEST(OiioPlugin, ErrorsAreOiiotoolErrorsNotCrashes)
{
    if (system("command -v oiiotool > /dev/null") != 0)
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = mcdn_test::temp_dir("plugin_errors");
    for (const auto& [query, message] : std::vector<std::pair<std::string, std::string>> {
             { "x.mcdn?in=/nonexistent.exr", "/nonexistent.exr: no such file" },
             { box_query("nfor,blur"), "unknown stage 'blur'" },
             { box_query("cnn") + "&cnn.weights=/nonexistent.mcdnw", "/nonexistent.mcdnw" },
             { box_query("nfor") + "&colour=1", "unknown key 'colour'" },
             { box_query("mix"), "mix needs sure before it" },
             { box_query("nfor") + "&nfor.windw=19", "windw=19: unknown setting of nfor" },
             { box_query("nfor") + "&nfor.window=4", "nfor.window=4 must be an odd width" },
             { box_query("nfor") + "&nfr.window=19", "'nfr.window': not a stage setting" },
         }) {
        auto run = oiiotool(quote(query) + " -o " + quote(dir + "/out.exr"));
        EXPECT_NE(run.exit_code, 0) << query;
        EXPECT_LT(run.exit_code, 128) << "crashed: " << run.output;
        EXPECT_NE(run.output.find(message), std::string::npos) << run.output;
    }
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.exr"));
}

// The README's example as it is written: a render and its variance, no chain (denoise), no
// preset (detected), plain oiiotool's own colour names without $OCIO.
TEST(OiioPlugin, TheReadmeExampleWorksWithoutOcio)
{
    if (!mcdn_test::has_oiiotool())
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = mcdn_test::temp_dir("plugin_readme");
    std::string d = mcdn_test::test_data("box16/");
    auto run = mcdn_test::run_command(
        "env -u OCIO OIIO_LIBRARY_PATH='" + std::string(MCDN_PLUGIN_DIR) + "' timeout 300 oiiotool "
        + quote("shot.mcdn?in=" + d + "box_0016spp.exr&variance=" + d + "box_0016spp_var.exr")
        + " --ch R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,B=ViewLayer.Combined.B"
          " --colorconvert linear sRGB -o "
        + quote(dir + "/preview.png"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/preview.png"));
    // The denoised image itself, below the render's error.
    run = oiiotool(
        quote("shot.mcdn?in=" + d + "box_0016spp.exr&variance=" + d + "box_0016spp_var.exr")
        + " --ch R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,B=ViewLayer.Combined.B -o "
        + quote(dir + "/denoised.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    auto noisy =
        oiiotool(quote(d + "box_0016spp.exr")
                 + " --ch R=ViewLayer.Combined.R,G=ViewLayer.Combined.G,B=ViewLayer.Combined.B -o "
                 + quote(dir + "/noisy.exr"));
    ASSERT_EQ(noisy.exit_code, 0) << noisy.output;
    EXPECT_LT(relmse_of(dir + "/denoised.exr"), 0.5 * relmse_of(dir + "/noisy.exr"));
}
