// Outputs never cost a file (issue: never lose a file): -o naming an input, a signal during
// the write, a read-only or directory output, and what a killed run left behind.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <thread>

#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/io.h"

#include "mcdn_test.h"

using namespace mcdn_test;
namespace Filesystem = OIIO::Filesystem;

namespace {

std::string contents(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

// A copy of the box16 render (and its variance) in `dir`, to be clobbered or not.
std::string copy_box(const std::string& dir, const std::string& name = "render.exr")
{
    std::string error;
    std::string dst = dir + "/" + name;
    EXPECT_TRUE(Filesystem::copy(test_data("box16/box_0016spp.exr"), dst, error)) << error;
    EXPECT_TRUE(Filesystem::copy(test_data("box16/box_0016spp_var.exr"), dir + "/var.exr", error));
    return dst;
}

std::vector<std::string> leftovers(const std::string& dir)
{
    std::vector<std::string> names;
    for (const auto& entry : std::filesystem::directory_iterator(dir)) {
        std::string name = entry.path().filename().string();
        if (name.find("mcdn-tmp") != std::string::npos || name.find(".tmp") != std::string::npos)
            names.push_back(name);
    }
    return names;
}

}  // namespace

TEST(Output, NamingAnInputIsRefusedBeforeAnyWork)
{
    std::string dir = temp_dir("out_input");
    std::string render = copy_box(dir);
    const std::string before = contents(render), var_before = contents(dir + "/var.exr");
    ASSERT_EQ(::link(render.c_str(), (dir + "/hardlink.exr").c_str()), 0);
    ASSERT_EQ(::symlink(render.c_str(), (dir + "/symlink.exr").c_str()), 0);
    for (std::string out :
         { render, dir + "/./render.exr", dir + "/../" + Filesystem::filename(dir) + "/render.exr",
           dir + "/hardlink.exr", dir + "/symlink.exr", dir + "/var.exr" }) {
        for (std::string chain : { "", "--cnn", "--prefilter --nfor" }) {
            mcdn_test::Run run =
                run_mcdntool("-i " + quote(render) + " -i:as=variance " + quote(dir + "/var.exr")
                             + " " + chain + " -o " + quote(out));
            EXPECT_EQ(run.exit_code, 1) << out << " " << chain << ": " << run.output;
            EXPECT_NE(run.output.find("also an input"), std::string::npos) << run.output;
            // One line, and before any stage (--nfor without halves would fail otherwise).
            EXPECT_EQ(std::count(run.output.begin(), run.output.end(), '\n'), 1) << run.output;
        }
    }
    EXPECT_EQ(contents(render), before);
    EXPECT_EQ(contents(dir + "/var.exr"), var_before);
    EXPECT_TRUE(leftovers(dir).empty());
    // The reference of --metrics is an input too.
    mcdn_test::Run run = run_mcdntool("-i " + quote(render) + " --metrics "
                                      + quote(dir + "/var.exr") + " -o " + quote(dir + "/var.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_EQ(contents(dir + "/var.exr"), var_before);
}

TEST(Output, WriteImageRefusesTheBuffersOwnInputs)
{
    // The library's writer (the Python module's write) knows the merged buffer's files.
    std::string dir = temp_dir("out_write_input");
    std::string render = copy_box(dir);
    const std::string before = contents(render);
    OIIO::ImageBuf merged;
    ASSERT_TRUE(mcdn::read_inputs(merged, { { render, mcdn::InputKind::Mean },
                                            { dir + "/var.exr", mcdn::InputKind::Variance } }));
    std::string error;
    EXPECT_FALSE(mcdn::write_image(merged, dir + "/var.exr", {}, error));
    EXPECT_NE(error.find("also an input"), std::string::npos) << error;
    EXPECT_FALSE(mcdn::write_image(merged, render, {}, error));
    EXPECT_EQ(contents(render), before);
    EXPECT_TRUE(mcdn::write_image(merged, dir + "/out.exr", {}, error)) << error;
}

TEST(Output, ADirectoryOrAMissingFolderFailsBeforeAnyWork)
{
    std::string dir = temp_dir("out_dir");
    std::string render = copy_box(dir);
    Filesystem::create_directory(dir + "/sub");
    // --nfor without halves fails at its stage: the output's error must come first.
    mcdn_test::Run run = run_mcdntool("-i " + quote(render) + " --nfor -o " + quote(dir + "/sub"));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("is a directory"), std::string::npos) << run.output;
    // A missing folder is made as the file is written (mkdir -p): not when the chain fails
    // first; a file where a folder would be fails before any work.
    run = run_mcdntool("-i " + quote(render) + " --nfor -o " + quote(dir + "/no/such/out.exr"));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("nfor needs two half buffers"), std::string::npos) << run.output;
    EXPECT_FALSE(Filesystem::exists(dir + "/no"));
    run = run_mcdntool("-i " + quote(render) + " --nfor -o " + quote(render + "/such/out.exr"));
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("is not a folder"), std::string::npos) << run.output;
    run = run_mcdntool("-i " + quote(render) + " --nfor --heatmap:ref=" + quote(render) + " "
                       + quote(dir + "/sub"));
    EXPECT_NE(run.output.find("is a directory"), std::string::npos) << run.output;
}

TEST(Output, AFileTheUserCannotWriteIsNotReplaced)
{
    std::string dir = temp_dir("out_readonly");
    std::string render = copy_box(dir);
    std::string out = dir + "/out.exr";
    {
        std::ofstream(out) << "keep me";
    }
    ::chmod(out.c_str(), 0444);
    ::chmod(dir.c_str(), 0777);  // the folder is writable: only the file's mode protects it
    ::chmod(render.c_str(), 0644);
    // root may write anything (as cp and oiiotool let it): run as root without the
    // capabilities that override file permissions, as an ordinary user would be.
    std::string as_user = ::geteuid() == 0 ? kWithoutRootsPowers : "";
    if (::geteuid() == 0 && std::system("command -v setpriv >/dev/null") != 0)
        GTEST_SKIP() << "running as root without setpriv";
    mcdn_test::Run run = run_mcdntool("-i " + quote(render) + " -o " + quote(out), "", as_user);
    const std::string& output = run.output;
    EXPECT_EQ(run.exit_code, 1) << output;
    EXPECT_NE(output.find("cannot be written"), std::string::npos) << output;
    EXPECT_EQ(contents(out), "keep me");
}

namespace {

// A frame whose write takes long enough to be interrupted: 2048² with 40 channels.
std::string big_frame(const std::string& dir)
{
    std::vector<std::string> names = { "R", "G", "B" };
    for (int i = 0; i < 37; ++i)
        names.push_back("extra" + std::to_string(i));
    OIIO::ImageBuf buf = make_image(2048, 2048, names, [](int x, int y, int c) {
        return float(((x * 7 + y * 13 + c * 31) % 97)) / 97.0f;
    });
    std::string path = dir + "/big.exr";
    buf.specmod().attribute("compression", "none");
    EXPECT_TRUE(buf.write(path)) << buf.geterror();
    return path;
}

}  // namespace

TEST(Output, ASignalDuringTheWriteLeavesNoFile)
{
    std::string dir = temp_dir("out_signal");
    std::string input = big_frame(dir);
    for (int sig : { SIGINT, SIGTERM, SIGHUP }) {
        std::string out = dir + "/out.exr";
        pid_t pid = ::fork();
        ASSERT_GE(pid, 0);
        if (pid == 0) {
            ::execl(MCDNTOOL, MCDNTOOL, "--aov:preset=generic", "-i", input.c_str(),
                    "-o:compression=zip", out.c_str(), (char*)nullptr);
            ::_exit(127);
        }
        // Waits for the temporary to appear, then interrupts the write.
        bool seen = false;
        for (int i = 0; i < 60000 && !seen; ++i) {
            seen = !leftovers(dir).empty();
            if (!seen)
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
        EXPECT_TRUE(seen) << "no temporary file appeared";
        ::kill(pid, sig);
        int status = 0;
        ::waitpid(pid, &status, 0);
        // Killed by the signal (the shell's 128 + N), not a normal exit.
        EXPECT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == sig) << "signal " << sig;
        EXPECT_TRUE(leftovers(dir).empty()) << leftovers(dir)[0];
        EXPECT_FALSE(Filesystem::exists(out));
    }
}

TEST(Output, TemporariesOfAKilledRunAreRemovedByTheNextWrite)
{
    std::string dir = temp_dir("out_stale");
    std::string render = copy_box(dir);
    // A PID that runs (this test) keeps its file; one that does not (beyond pid_max) loses it
    // (on this host, in this PID namespace: RealFiles.AnotherHostsTemporaryIsNotRemoved).
    const std::string owner = "-0-" + mcdn::temporary_owner();
    std::string alive = dir + "/.out.exr.mcdn-tmp-" + std::to_string(::getpid()) + owner;
    std::string dead = dir + "/.out.exr.mcdn-tmp-99999999" + owner;
    std::string other = dir + "/.other.exr.mcdn-tmp-99999999" + owner;
    for (const auto& f : { alive, dead, other })
        std::ofstream(f) << "partial";
    mcdn_test::Run run = run_mcdntool("-i " + quote(render) + " -o " + quote(dir + "/out.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(Filesystem::exists(alive));
    EXPECT_FALSE(Filesystem::exists(dead));
    EXPECT_TRUE(Filesystem::exists(other));  // another output's
}
