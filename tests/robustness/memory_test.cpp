// A chain that cannot fit is refused before it starts, naming the sizes (a 4K Blender frame
// through --cnn --sure --mix was killed for memory at 21.9 GB on a 24 GB machine).
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include "mcdn_test.h"

using namespace mcdn_test;

namespace {

// A 3840x2160 EXR with Blender's 39 channels of zeros, written a scanline at a time (small
// on disk, and never a frame in memory): only its header is read by the check.
std::string uhd_frame(const std::string& dir)
{
    OIIO::ImageSpec spec(3840, 2160, 39, OIIO::TypeDesc::HALF);
    OIIO::ImageBuf box(test_data("box16/box_0016spp.exr"));
    spec.channelnames = box.spec().channelnames;
    spec.alpha_channel = spec.z_channel = -1;
    spec.attribute("compression", "zip");
    std::string path = dir + "/uhd.exr";
    auto out = OIIO::ImageOutput::create(path);
    EXPECT_TRUE(out && out->open(path, spec));
    std::vector<float> row(size_t(spec.width) * spec.nchannels, 0.0f);
    for (int y = 0; y < spec.height; ++y)
        out->write_scanline(y, 0, OIIO::TypeDesc::FLOAT, row.data());
    out->close();
    return path;
}

}  // namespace

TEST(Memory, AChainThatCannotFitIsRefusedBeforeItStarts)
{
    std::string dir = temp_dir("memory_uhd");
    std::string f = quote(uhd_frame(dir));
    // Render, variance and both halves, 156 channels (the render's 39 and the colour of the
    // others read at least), 2 threads: streamed in bands it needs the input and one band
    // with its halo (3.8 GB by the estimate; 2.4 GB measured on this frame of zeros), more
    // than a 2 GB slot has.
    mcdn_test::Run run = run_mcdntool(
        "--threads 2 -i " + f + " -i:as=variance " + f + " -i:as=halfA " + f + " -i:as=halfB " + f
            + " --cnn --sure --mix:model=net -o " + quote(dir + "/out.exr"),
        "MCDN_MEMORY_LIMIT=2G");
    const std::string& output = run.output;
    EXPECT_EQ(run.exit_code, 1) << output;
    EXPECT_NE(output.find("a 8 Mpixel frame with 156 channels (48 read at least) needs about"),
              std::string::npos)
        << output;
    EXPECT_NE(output.find("2.0 GB are available"), std::string::npos) << output;
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.exr"));
}

// The estimate counts the channels that are read (the render's, and of the variance and
// halves the roles' faces), not every channel of every file: a 512x512 Blender frame in four
// files (156 channels, 48 read at least) through the best chain fits a 1.2 GB slot, which
// counting all 156 (1.4 GB) refused.
TEST(Memory, OnlyTheChannelsReadCount)
{
    const std::string dir = temp_dir("memory_read");
    OIIO::ImageBuf box(test_data("box16/box_0016spp.exr"));
    OIIO::ImageSpec spec(512, 512, 39, OIIO::TypeDesc::HALF);
    spec.channelnames = box.spec().channelnames;
    spec.alpha_channel = spec.z_channel = -1;
    OIIO::ImageBuf frame(spec);
    OIIO::ImageBufAlgo::fill(frame, { 0.25f });
    const std::string f = quote(dir + "/frame.exr");
    ASSERT_TRUE(frame.write(dir + "/frame.exr"));
    mcdn_test::Run run = run_mcdntool(
        "--threads 2 -i " + f + " -i:as=variance " + f + " -i:as=halfA " + f + " -i:as=halfB " + f
            + " --cnn --sure --mix:model=net -o " + quote(dir + "/out.exr"),
        "MCDN_MEMORY_LIMIT=1.2G");
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/out.exr"));
}

TEST(Memory, TheLimitCanBeAFarmSlots)
{
    std::string box = quote(test_data("box16/box_0016spp.exr"));
    mcdn_test::Run run =
        run_mcdntool("-i " + box + " --cnn -o " + quote(temp_dir("memory_low") + "/out.exr"),
                     "MCDN_MEMORY_LIMIT=1M");
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("0.0 GB are available"), std::string::npos) << run.output;
    run = run_mcdntool("-i " + box + " --cnn -o " + quote(temp_dir("memory_ok") + "/out.exr"),
                       "MCDN_MEMORY_LIMIT=100G");
    EXPECT_EQ(run.exit_code, 0) << run.output;
    // A limit that is not a size is an error, not "no limit".
    run = run_mcdntool("-i " + box + " --cnn -o " + quote(temp_dir("memory_bad") + "/out.exr"),
                       "MCDN_MEMORY_LIMIT=lots");
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("MCDN_MEMORY_LIMIT=lots: needs a number"), std::string::npos)
        << run.output;
}
