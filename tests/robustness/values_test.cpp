// Inputs that could hang or crash a front end, and values that could pass silently: nested and
// looping recipes, thread counts, compressions, SURE's step (one rule in every front end).
#include <fstream>

#include "mcdn/io.h"
#include "mcdn/threads.h"

#include "mcdn_test.h"

using namespace mcdn_test;

namespace {

mcdn_test::Run oiiotool(const std::string& args)
{
    return run_oiiotool(args);
}

void write_file(const std::string& path, const std::string& text)
{
    std::ofstream(path) << text;
}

const std::string kBox = test_data("box16/box_0016spp.exr");

}  // namespace

TEST(Recipes, ALoopIsAnErrorNotAHang)
{
    if (!has_oiiotool())
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = temp_dir("recipe_loop");
    write_file(dir + "/self.mcdn", "in = self.mcdn\nchain = cnn\n");
    write_file(dir + "/a.mcdn", "in = b.mcdn\nchain = cnn\n");
    write_file(dir + "/b.mcdn", "in = ./a.mcdn\nchain = cnn\n");
    // The query form too: its `in` names a recipe file that loops.
    for (std::string recipe :
         { dir + "/self.mcdn", dir + "/a.mcdn", dir + "/q.mcdn?in=" + dir + "/a.mcdn&chain=cnn" }) {
        mcdn_test::Run run = oiiotool(quote(recipe) + " -o " + quote(dir + "/out.exr"));
        EXPECT_EQ(run.exit_code, 1) << recipe << ": " << run.output;
        EXPECT_NE(run.output.find("recipe loop"), std::string::npos) << run.output;
    }
}

TEST(Recipes, ANestedRecipeWorks)
{
    if (!has_oiiotool())
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = temp_dir("recipe_nested");
    write_file(dir + "/inner.mcdn", "in = " + kBox + "\nchain = cnn\n");
    write_file(dir + "/outer.mcdn", "in = inner.mcdn\nchain = cnn\n");
    for (std::string recipe :
         { dir + "/outer.mcdn", dir + "/x.mcdn?in=" + dir + "/inner.mcdn&chain=cnn" }) {
        mcdn_test::Run run = oiiotool(quote(recipe) + " -o " + quote(dir + "/out.exr"));
        EXPECT_EQ(run.exit_code, 0) << recipe << ": " << run.output;
    }
    // Deeper than the limit: an error naming the limit.
    for (int i = 1; i <= 10; ++i)
        write_file(dir + "/d" + std::to_string(i) + ".mcdn",
                   "in = " + (i == 10 ? kBox : "d" + std::to_string(i + 1) + ".mcdn")
                       + "\nchain = cnn\n");
    mcdn_test::Run run = oiiotool(quote(dir + "/d1.mcdn") + " -o " + quote(dir + "/deep.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("nested more than"), std::string::npos) << run.output;
}

TEST(Threads, OneRuleInTheLibrary)
{
    std::string error;
    int n = -1;
    EXPECT_TRUE(mcdn::check_threads(0, error));
    EXPECT_TRUE(mcdn::check_threads(mcdn::kMaxThreads, error));
    for (int bad : { -1, -5, mcdn::kMaxThreads + 1, 65537, 70000 })
        EXPECT_FALSE(mcdn::check_threads(bad, error)) << bad;
    EXPECT_TRUE(mcdn::parse_threads("7", n, error));
    EXPECT_EQ(n, 7);
    for (const char* bad : { "abc", "-5", "70000", "", "1.5", "99999999999999" })
        EXPECT_FALSE(mcdn::parse_threads(bad, n, error)) << bad;
    EXPECT_NE(error.find("from 0 (all cores) to"), std::string::npos) << error;
}

TEST(Threads, TooManyIsAnErrorInEveryFrontEnd)
{
    for (std::string n : { "70000", "65537", "abc", "-5" }) {
        mcdn_test::Run run =
            run_mcdntool("-i " + quote(kBox) + " --threads " + n + " --cnn -o /dev/null");
        EXPECT_EQ(run.exit_code, 1) << n << ": " << run.output;
        EXPECT_NE(run.output.find("threads"), std::string::npos) << run.output;
    }
    if (!has_oiiotool())
        GTEST_SKIP() << "oiiotool not installed";
    std::string dir = temp_dir("threads_plugin");
    for (std::string n : { "70000", "abc", "-5" }) {
        mcdn_test::Run run = oiiotool(quote("x.mcdn?in=" + kBox + "&chain=cnn&threads=" + n)
                                      + " -o " + quote(dir + "/out.exr"));
        EXPECT_EQ(run.exit_code, 1) << n << ": " << run.output;
        EXPECT_NE(run.output.find("threads=" + n), std::string::npos) << run.output;
    }
}

TEST(Values, SilentlyAcceptedValuesAreErrors)
{
    std::string dir = temp_dir("values");
    for (std::string args : { "-o:compression=bogus", "-o:compression=ZIP" }) {
        mcdn_test::Run run =
            run_mcdntool("-i " + quote(kBox) + " --cnn " + args + " " + quote(dir + "/out.exr"));
        EXPECT_EQ(run.exit_code, 1) << args << ": " << run.output;
        EXPECT_NE(run.output.find("compression="), std::string::npos) << run.output;
        EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.exr"));
    }
    for (std::string eps : { "0", "-1e-3", "0.5" }) {
        mcdn_test::Run run = run_mcdntool(
            "-i " + quote(kBox) + " -i:as=variance " + quote(test_data("box16/box_0016spp_var.exr"))
            + " --cnn --sure:eps=" + eps + " -o " + quote(dir + "/out.exr"));
        EXPECT_EQ(run.exit_code, 1) << eps << ": " << run.output;
        EXPECT_NE(run.output.find("eps=" + eps), std::string::npos) << run.output;
    }
    mcdn_test::Run run =
        run_mcdntool("-i " + quote(kBox) + " -o:compression=dwaa " + quote(dir + "/ok.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    // Levels, for the library's and Python's writers.
    std::string error;
    for (const char* ok : { "none", "zip", "zip:9", "piz", "dwaa:45", "b44a" })
        EXPECT_TRUE(mcdn::check_compression(ok, error)) << ok;
    for (const char* bad : { "zip:x", "piz:3", "bogus", "zip:-1" })
        EXPECT_FALSE(mcdn::check_compression(bad, error)) << bad;
}
