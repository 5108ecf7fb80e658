// What every test folder shares: where the data is, building small buffers, running the CLI.
#pragma once

#include <cstdio>
#include <cstdlib>
#include <unistd.h>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>

namespace mcdn_test {

inline std::string test_data(const std::string& rel)
{
    return std::string(MCDN_TEST_DATA) + "/" + rel;
}

/// Path inside ../shared/data, or "" when that checkout is absent (a user's clone).
inline std::string shared_data(const std::string& rel)
{
    std::string path = std::string(MCDN_SHARED_DATA) + "/" + rel;
    return OIIO::Filesystem::exists(path) ? path : std::string();
}

#define MCDN_REQUIRE_SHARED(var, rel)                                                              \
    std::string var = mcdn_test::shared_data(rel);                                                 \
    if (var.empty())                                                                               \
        GTEST_SKIP() << "../shared/data/" << rel << " absent (user clone): skipped";

/// A fresh empty directory for one test's outputs, of this process (two test runs at once
/// on one machine do not share it), removed when the process exits.
inline std::string temp_dir(const std::string& name)
{
    struct Made {
        std::vector<std::string> dirs;
        ~Made()
        {
            for (const std::string& dir : dirs)
                OIIO::Filesystem::remove_all(dir);
        }
    };
    static Made made;
    std::string dir = OIIO::Filesystem::temp_directory_path() + "/mcdn_test_" + name + "_"
                      + std::to_string(getpid());
    OIIO::Filesystem::remove_all(dir);
    OIIO::Filesystem::create_directory(dir);
    made.dirs.push_back(dir);
    return dir;
}

/// A float buffer with the given channel names, every value from `fill(x, y, c)`.
template <class F>
OIIO::ImageBuf make_image(int w, int h, const std::vector<std::string>& names, F fill)
{
    OIIO::ImageSpec spec(w, h, int(names.size()), OIIO::TypeDesc::FLOAT);
    spec.channelnames = names;
    spec.alpha_channel = spec.z_channel = -1;
    OIIO::ImageBuf buf(spec);
    float* p = static_cast<float*>(buf.localpixels());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < int(names.size()); ++c)
                p[(size_t(y) * w + x) * names.size() + c] = fill(x, y, c);
    return buf;
}

struct Run {
    int exit_code;
    std::string output;  // stdout and stderr together
};

/// Runs a shell command line, stderr with stdout; exit_code -1 when it did not exit (a
/// signal).
inline Run run_command(const std::string& command_line)
{
    Run run { -1, "" };
    FILE* pipe = popen((command_line + " 2>&1").c_str(), "r");
    if (!pipe)
        return run;
    char line[4096];
    while (fgets(line, sizeof line, pipe))
        run.output += line;
    int status = pclose(pipe);
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
    return run;
}

/// Runs the built mcdntool with `args` (a shell-quoted string); `env` (VAR=value ...) and
/// `prefix` (a command such as kWithoutRootsPowers) go before it.
inline Run run_mcdntool(const std::string& args, const std::string& env = "",
                        const std::string& prefix = "")
{
    return run_command(env + (env.empty() ? "" : " ") + prefix + "'" + MCDNTOOL + "' " + args);
}

/// Runs Debian's oiiotool with the built plugin, under a time limit (exit 124 if it hangs);
/// `env`: more NAME=value settings for it.
inline Run run_oiiotool(const std::string& args, const std::string& env = "")
{
    return run_command(env + (env.empty() ? "" : " ") + "OIIO_LIBRARY_PATH='"
                       + std::string(MCDN_PLUGIN_DIR) + "' timeout 300 oiiotool " + args);
}

/// True when oiiotool is on PATH (tests that need it skip otherwise).
inline bool has_oiiotool()
{
    return std::system("command -v oiiotool >/dev/null") == 0;
}

/// A command prefix that runs it as root without the capabilities that override file
/// permissions (CAP_DAC_OVERRIDE, ...): permissions then apply as to any user, and a build
/// tree under /root stays reachable (an unprivileged user could not load it there).
const std::string kWithoutRootsPowers = "setpriv --bounding-set=-all --inh-caps=-all ";

inline std::string quote(const std::string& s)
{
    return "'" + s + "'";
}

/// What -o writes of `expected` and `result` (the "mcdn:output_channels" of `input`, the
/// frame read with every channel), channel by channel by name: identical.
inline void expect_output_channels_equal(const OIIO::ImageBuf& expected,
                                         const OIIO::ImageBuf& result, const OIIO::ImageBuf& input)
{
    const std::vector<std::string> output =
        OIIO::Strutil::splits(input.spec().get_string_attribute("mcdn:output_channels"), "\n");
    ASSERT_FALSE(output.empty());
    for (const std::string& name : output) {
        const int e = expected.spec().channelindex(name), r = result.spec().channelindex(name);
        ASSERT_GE(e, 0) << name;
        ASSERT_GE(r, 0) << name;
        OIIO::ImageBuf a = OIIO::ImageBufAlgo::channels(expected, 1, { e });
        OIIO::ImageBuf b = OIIO::ImageBufAlgo::channels(result, 1, { r });
        EXPECT_EQ(OIIO::ImageBufAlgo::compare(a, b, 0, 0).maxerror, 0.0) << name;
    }
}

}  // namespace mcdn_test
