// Results that could be silently wrong, and errors that must point the right way: a variance
// file without a variance, fireflies beyond half, NaN in pass-through channels, unreadable
// inputs, recipes that fail, and features a run goes without.
#include <cmath>
#include <fstream>

#include <sys/stat.h>
#include <unistd.h>

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn_test.h"

using namespace mcdn_test;
namespace IBA = OIIO::ImageBufAlgo;

namespace {

const std::string kBox = test_data("box16/box_0016spp.exr");
const std::string kVar = test_data("box16/box_0016spp_var.exr");

// The box render with `change` applied to its pixels, written to `path`.
template <class F> std::string edited_box(const std::string& path, F change)
{
    OIIO::ImageBuf box(kBox);
    box.read(0, 0, true, OIIO::TypeDesc::FLOAT);
    OIIO::ImageBuf copy = box.copy(OIIO::TypeDesc::FLOAT);
    change(copy);
    EXPECT_TRUE(copy.write(path)) << copy.geterror();
    return path;
}

void set_value(OIIO::ImageBuf& buf, const std::string& channel, int x, int y, float v)
{
    int c = buf.spec().channelindex(channel);
    ASSERT_GE(c, 0) << channel;
    float* p = static_cast<float*>(buf.localpixels());
    p[(size_t(y) * buf.spec().width + x) * buf.nchannels() + c] = v;
}

}  // namespace

TEST(Silent, AVarianceFileWithoutAColorVarianceIsAnError)
{
    std::string dir = temp_dir("silent_var");
    // A PNG renamed .exr: OIIO reads it by its content, channels R,G,B,A.
    OIIO::ImageBuf png =
        make_image(64, 64, { "R", "G", "B", "A" }, [](int, int, int) { return 0.5f; });
    ASSERT_TRUE(png.write(dir + "/var.png"));
    ASSERT_EQ(std::rename((dir + "/var.png").c_str(), (dir + "/var.exr").c_str()), 0);
    // An EXR without the blue channel's variance.
    OIIO::ImageBuf var(kVar);
    std::vector<int> keep;
    std::vector<std::string> names;
    for (int c = 0; c < var.nchannels(); ++c)
        if (var.spec().channelnames[c] != "ViewLayer.Combined.B") {
            keep.push_back(c);
            names.push_back(var.spec().channelnames[c]);
        }
    OIIO::ImageBuf no_b = IBA::channels(var, int(keep.size()), keep, {}, names);
    ASSERT_TRUE(no_b.write(dir + "/var_no_b.exr"));
    for (std::string file : { dir + "/var.exr", dir + "/var_no_b.exr" })
        for (std::string chain : { "--nfor", "--cnn", "" }) {
            mcdn_test::Run run =
                run_mcdntool("-i " + quote(kBox) + " -i:as=variance " + quote(file)
                             + " -i:as=halfA " + quote(test_data("box16/box_0016spp_A.exr"))
                             + " -i:as=halfB " + quote(test_data("box16/box_0016spp_B.exr")) + " "
                             + chain + " -o " + quote(dir + "/out.exr"));
            EXPECT_EQ(run.exit_code, 1) << file << chain << ": " << run.output;
            EXPECT_NE(run.output.find(file + ": given with -i:as=variance but has no variance"),
                      std::string::npos)
                << run.output;
            EXPECT_NE(run.output.find("variance.ViewLayer.Combined.B"), std::string::npos)
                << run.output;  // the channels looked for
        }
}

TEST(Silent, HalfOutputClampsFirefliesWithAWarning)
{
    std::string dir = temp_dir("silent_half");
    std::string in = edited_box(dir + "/firefly.exr", [](OIIO::ImageBuf& b) {
        for (int i = 0; i < 3; ++i)
            set_value(b, "ViewLayer.Combined.R", 10 + i, 20, 1e6f);
    });
    mcdn_test::Run run =
        run_mcdntool("-i " + quote(in) + " -o:datatype=half " + quote(dir + "/out.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("warning: " + dir
                              + "/out.exr: channel ViewLayer.Combined.R: 3 "
                                "values beyond half's range clamped to +-65504"),
              std::string::npos)
        << run.output;
    OIIO::ImageBuf out(dir + "/out.exr");
    auto stats = IBA::computePixelStats(out);
    for (size_t c = 0; c < stats.nancount.size(); ++c)
        EXPECT_EQ(stats.nancount[c] + stats.infcount[c], 0u) << out.spec().channelnames[c];
    EXPECT_EQ(stats.max[out.spec().channelindex("ViewLayer.Combined.R")], 65504.0f);
    // float keeps them, without a word.
    run = run_mcdntool("-i " + quote(in) + " -o " + quote(dir + "/float.exr"));
    EXPECT_EQ(run.output.find("warning"), std::string::npos) << run.output;
}

TEST(Silent, NanInPassThroughChannelsIsNamedAndFixnanRepairsIt)
{
    std::string dir = temp_dir("silent_nan");
    std::string in = edited_box(dir + "/nan.exr", [](OIIO::ImageBuf& b) {
        set_value(b, "ViewLayer.Combined.A", 3, 4, std::nanf(""));
        set_value(b, "ViewLayer.Normal.X", 5, 6, std::nanf(""));
        set_value(b, "ViewLayer.Normal.X", 7, 6, INFINITY);
    });
    mcdn_test::Run run = run_mcdntool("-i " + quote(in) + " --cnn -o " + quote(dir + "/out.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("channel ViewLayer.Combined.A has 1 NaN and 0 Inf"),
              std::string::npos)
        << run.output;
    EXPECT_NE(run.output.find("channel ViewLayer.Normal.X has 1 NaN and 1 Inf"), std::string::npos)
        << run.output;
    for (std::string mode : { "black", "box3" }) {
        run = run_mcdntool("-i " + quote(in) + " --cnn --fixnan " + mode + " -o "
                           + quote(dir + "/fixed.exr"));
        EXPECT_EQ(run.exit_code, 0) << run.output;
        EXPECT_EQ(run.output.find("warning"), std::string::npos) << run.output;
        auto stats = IBA::computePixelStats(OIIO::ImageBuf(dir + "/fixed.exr"));
        for (size_t c = 0; c < stats.nancount.size(); ++c)
            EXPECT_EQ(stats.nancount[c] + stats.infcount[c], 0u);
    }
    run = run_mcdntool("-i " + quote(in) + " --fixnan error -o " + quote(dir + "/e.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    run = run_mcdntool("-i " + quote(in) + " --fixnan zero -o " + quote(dir + "/e.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("none, black, box3 or error"), std::string::npos) << run.output;
}

TEST(Silent, AnUnreadableInputSaysSo)
{
    if (::geteuid() == 0 && std::system("command -v setpriv >/dev/null") != 0)
        GTEST_SKIP() << "running as root without setpriv";
    std::string dir = temp_dir("silent_perm");
    ::chmod(dir.c_str(), 0777);
    std::string in = dir + "/secret.exr";
    std::string error;
    ASSERT_TRUE(OIIO::Filesystem::copy(kBox, in, error));
    ::chmod(in.c_str(), 0000);
    std::string as_user = ::geteuid() == 0 ? kWithoutRootsPowers : "";
    const std::string output =
        run_mcdntool("-i " + quote(in) + " -o " + quote(dir + "/out.exr"), "", as_user).output;
    EXPECT_NE(output.find(in + ": cannot read: Permission denied"), std::string::npos) << output;
    EXPECT_EQ(output.find("not an OpenEXR"), std::string::npos) << output;
}

TEST(Silent, TheMissingFeaturesAreNamedWithV)
{
    mcdn_test::Run run = run_mcdntool("-v -i " + quote(kBox) + " --cnn -o /dev/null");
    EXPECT_NE(run.output.find("features found: albedo, normal, depth, diffuse_color, "
                              "glossy_color; missing: none"),
              std::string::npos)
        << run.output;
    std::string dir = temp_dir("silent_features");
    OIIO::ImageBuf box(kBox);
    std::vector<int> keep;
    for (int c = 0; c < box.nchannels(); ++c)
        if (box.spec().channelnames[c].find("Albedo") == std::string::npos)
            keep.push_back(c);
    OIIO::ImageBuf no_albedo = IBA::channels(box, int(keep.size()), keep);
    ASSERT_TRUE(no_albedo.write(dir + "/no_albedo.exr"));
    run = run_mcdntool("-v -i " + quote(dir + "/no_albedo.exr") + " --cnn -o /dev/null");
    EXPECT_NE(run.output.find("missing: albedo (nfor and prefilter leave them out"),
              std::string::npos)
        << run.output;
}

namespace {

mcdn_test::Run oiiotool(const std::string& args)
{
    return run_oiiotool(args);
}

}  // namespace

TEST(Silent, RecipesSayWhatIsWrong)
{
    if (!has_oiiotool())
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = temp_dir("silent_recipe");
    // A failing recipe: --info shows the error, not a valid 1x1 image.
    std::ofstream(dir + "/bad.mcdn") << "in = " << kBox << "\nchain = nfor\n";
    mcdn_test::Run run = oiiotool("--info -v " + quote(dir + "/bad.mcdn"));
    EXPECT_NE(run.output.find("mcdn recipe error: nfor"), std::string::npos) << run.output;
    // '#' inside a path is part of it; a comment needs white space before it.
    std::string error;
    ASSERT_TRUE(OIIO::Filesystem::copy(kBox, dir + "/shot#1.exr", error));
    std::ofstream(dir + "/hash.mcdn") << "in = shot#1.exr   # the render\nchain = cnn\n";
    run = oiiotool(quote(dir + "/hash.mcdn") + " -o " + quote(dir + "/hash.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    // A UTF-8 byte order mark before the first key.
    std::ofstream(dir + "/bom.mcdn") << "\xEF\xBB\xBFin = " << kBox << "\nchain = cnn\n";
    run = oiiotool(quote(dir + "/bom.mcdn") + " -o " + quote(dir + "/bom.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    // %00 in a query path is an error, not a silently shorter path.
    run = oiiotool(quote("x.mcdn?in=" + kBox + "%00.junk&chain=cnn") + " -o "
                   + quote(dir + "/nul.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("%00"), std::string::npos) << run.output;
}
