// Every chain gives the same file for any thread count, and again when run again: whole
// mcdntool processes, their output files' pixels compared bit for bit (the metadata differ
// by the command line recorded in Exif:ImageHistory).
#include <fstream>
#include <iterator>

#include "mcdn_test.h"

using namespace mcdn_test;

namespace {

std::string contents(const std::string& path)
{
    OIIO::ImageBuf image(path);
    if (!image.read(0, 0, true, OIIO::TypeDesc::FLOAT))
        return {};
    const float* px = static_cast<const float*>(image.localpixels());
    std::string names = OIIO::Strutil::join(image.spec().channelnames, ",");
    return names
           + std::string(reinterpret_cast<const char*>(px),
                         image.spec().image_pixels() * image.nchannels() * sizeof(float));
}

}  // namespace

TEST(Determinism, EveryChainIsTheSameForAnyThreadCountAndRun)
{
    std::string dir = temp_dir("determinism");
    const std::string b = test_data("box16/box_0016spp");
    const std::string inputs = "-i " + quote(b + ".exr") + " -i:as=variance "
                               + quote(b + "_var.exr") + " -i:as=halfA " + quote(b + "_A.exr")
                               + " -i:as=halfB " + quote(b + "_B.exr");
    const std::vector<std::string> chains = {
        "--prefilter --nfor",
        "--cnn",
        "--cnn --sure --mix:model=net",
        "--prefilter --nfor --sure:probes=2 --mix:model=analytic:alpha=1",
    };
    for (size_t k = 0; k < chains.size(); ++k) {
        std::string first;
        for (int threads : { 1, 2, 3, 7, 2 }) {  // 2 twice: a repeated run
            std::string out =
                dir + "/c" + std::to_string(k) + "_t" + std::to_string(threads) + ".exr";
            mcdn_test::Run run = run_mcdntool("--threads " + std::to_string(threads) + " " + inputs
                                              + " " + chains[k] + " -o " + quote(out));
            ASSERT_EQ(run.exit_code, 0) << chains[k] << ": " << run.output;
            std::string bytes = contents(out);
            ASSERT_FALSE(bytes.empty());
            if (first.empty())
                first = bytes;
            EXPECT_TRUE(bytes == first)
                << chains[k] << " with " << threads << " threads differs from 1 thread";
        }
    }
}
