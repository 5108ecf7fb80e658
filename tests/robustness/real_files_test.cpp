// Files as renderers and tools write them, and files that are not files: other parts of a
// multi-part EXR, tiled and MIP-mapped EXRs through every chain, FIFOs and devices where a
// file is expected, weights that are not weights, half buffers of another render, values
// no render holds, and the messages a TD reads (issue 43).
#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>

#include <sys/stat.h>
#include <unistd.h>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include "mcdn/io.h"

#include "mcdn_test.h"

using namespace mcdn_test;
namespace IBA = OIIO::ImageBufAlgo;

namespace {

const std::string kBox = test_data("box16/box_0016spp.exr");
const std::string kVar = test_data("box16/box_0016spp_var.exr");
const std::string kHalfA = test_data("box16/box_0016spp_A.exr");
const std::string kHalfB = test_data("box16/box_0016spp_B.exr");
const std::string kRef = test_data("box16/box_ref.exr");

// Every input of the box fixture as mcdntool arguments.
std::string box_inputs(const std::string& render = kBox, const std::string& a = kHalfA,
                       const std::string& b = kHalfB)
{
    return "-i " + quote(render) + " -i:as=variance " + quote(kVar) + " -i:as=halfA " + quote(a)
           + " -i:as=halfB " + quote(b);
}

OIIO::ImageBuf read_float(const std::string& path)
{
    OIIO::ImageBuf buf(path);
    EXPECT_TRUE(buf.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << path << buf.geterror();
    return buf;
}

// `src` written to `path` with `spec_change` applied to its spec (tiles, MIP levels).
template <class F> void write_with(const std::string& src, const std::string& path, F spec_change)
{
    OIIO::ImageBuf buf = read_float(src);
    OIIO::ImageSpec spec = buf.spec();
    spec_change(spec);
    auto out = OIIO::ImageOutput::create(path);
    ASSERT_TRUE(out);
    ASSERT_TRUE(out->open(path, spec)) << out->geterror();
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, buf.localpixels())) << out->geterror();
    ASSERT_TRUE(out->close());
}

double max_abs_difference(const std::string& a, const std::string& b)
{
    IBA::CompareResults r = IBA::compare(read_float(a), read_float(b), 0.0f, 0.0f);
    return r.maxerror;
}

bool ends_one_line(const mcdn_test::Run& run)
{
    return std::count(run.output.begin(), run.output.end(), '\n') == 1;
}

}  // namespace

// 1. -i:part=NAME of any part but the first read that part (it segfaulted comparing with a
// part 0 it had not read).
TEST(RealFiles, AnyPartOfAMultiPartFileIsRead)
{
    std::string dir = temp_dir("real_part");
    OIIO::ImageBuf render = read_float(kBox), var = read_float(kVar);
    OIIO::ImageSpec specs[2] = { render.spec(), var.spec() };
    specs[0].attribute("name", "rgba");
    specs[1].attribute("name", "variance");
    const std::string mp = dir + "/mp.exr";
    auto out = OIIO::ImageOutput::create(mp);
    ASSERT_TRUE(out->open(mp, 2, specs));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, render.localpixels()));
    ASSERT_TRUE(out->open(mp, specs[1], OIIO::ImageOutput::AppendSubimage));
    ASSERT_TRUE(out->write_image(OIIO::TypeDesc::FLOAT, var.localpixels()));
    ASSERT_TRUE(out->close());
    mcdn_test::Run run = run_mcdntool("-i:part=variance " + quote(mp) + " --info");
    EXPECT_EQ(run.exit_code, 0) << run.output;
    // The variance part as the variance, the render part as the render: as the two files.
    run = run_mcdntool("-i:part=rgba " + quote(mp) + " -i:as=variance:part=variance " + quote(mp)
                       + " --cnn -o " + quote(dir + "/parts.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    run = run_mcdntool("-i " + quote(kBox) + " -i:as=variance " + quote(kVar) + " --cnn -o "
                       + quote(dir + "/files.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_EQ(max_abs_difference(dir + "/parts.exr", dir + "/files.exr"), 0.0);
    run = run_mcdntool("-i:part=nothere " + quote(mp) + " --info");
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("no part named 'nothere' (parts: rgba, variance)"), std::string::npos)
        << run.output;
}

// 2 and the tiled-output failure: tiled (1-row and 1-column tiles included) and MIP-mapped
// inputs give, through every chain, what the same pixels in scanlines give.
TEST(RealFiles, TiledAndMipMappedInputsThroughEveryChain)
{
    std::string dir = temp_dir("real_tiled");
    struct Layout {
        std::string name;
        int tw, th;
        bool mip;
    };
    const Layout layouts[] = { { "t64", 64, 64, false },  { "t32x1", 32, 1, false },
                               { "t1x32", 1, 32, false }, { "t16", 16, 16, false },
                               { "t48x8", 48, 8, false }, { "mip", 32, 32, true } };
    const std::string chains[] = { "--denoise", "--cnn", "--prefilter --nfor",
                                   "--prefilter --nfor --sure --mix", "--cnn --sure --mix" };
    for (size_t i = 0; i < std::size(chains); ++i) {
        const std::string plain = dir + "/plain" + std::to_string(i) + ".exr";
        mcdn_test::Run run = run_mcdntool(box_inputs() + " " + chains[i] + " -o " + quote(plain));
        ASSERT_EQ(run.exit_code, 0) << chains[i] << ": " << run.output;
    }
    for (const Layout& l : layouts) {
        auto tiled = [&](const std::string& src, const std::string& tag) {
            const std::string path = dir + "/" + l.name + "_" + tag + ".exr";
            write_with(src, path, [&](OIIO::ImageSpec& s) {
                s.tile_width = l.tw;
                s.tile_height = l.th;
                s.tile_depth = 1;
                if (l.mip)
                    s.attribute("openexr:levelmode", 1);  // MIPMAP_LEVELS
            });
            return path;
        };
        if (l.mip) {
            // OIIO's EXR writer makes the levels only through make_texture (oiiotool -otex).
            const std::string path = dir + "/" + l.name + "_render.exr";
            OIIO::ImageBuf src = read_float(kBox);
            OIIO::ImageSpec config;
            config.tile_width = config.tile_height = 32;
            ASSERT_TRUE(IBA::make_texture(IBA::MakeTxTexture, src, path, config))
                << OIIO::geterror();
        }
        const std::string render =
            l.mip ? dir + "/" + l.name + "_render.exr" : tiled(kBox, "render");
        const std::string a = tiled(kHalfA, "A"), b = tiled(kHalfB, "B");
        {
            auto in = OIIO::ImageInput::open(render);
            ASSERT_TRUE(in);
            EXPECT_EQ(in->spec().tile_width, l.tw) << l.name;
            if (l.mip) {
                EXPECT_TRUE(in->seek_subimage(0, 1)) << "no second MIP level";
            }
        }
        for (size_t i = 0; i < std::size(chains); ++i) {
            const std::string out = dir + "/" + l.name + "_out" + std::to_string(i) + ".exr";
            mcdn_test::Run run =
                run_mcdntool(box_inputs(render, a, b) + " " + chains[i] + " -o " + quote(out));
            ASSERT_EQ(run.exit_code, 0) << l.name << " " << chains[i] << ": " << run.output;
            EXPECT_EQ(max_abs_difference(out, dir + "/plain" + std::to_string(i) + ".exr"), 0.0)
                << l.name << " " << chains[i];
            // The output is a plain scanline image of level 0.
            auto in = OIIO::ImageInput::open(out);
            ASSERT_TRUE(in);
            EXPECT_EQ(in->spec().tile_width, 0) << l.name;
            EXPECT_FALSE(in->seek_subimage(0, 1)) << l.name << ": MIP levels written";
        }
    }
}

// 4, 5, 6: what is not a regular file is a one-line error, at once: no hang, no gigabytes
// read, no uncaught exception.
TEST(RealFiles, FifosAndDevicesAreRefusedAtOnce)
{
    std::string dir = temp_dir("real_fifo");
    const std::string fifo = dir + "/fifo.exr";
    ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
    const std::string out = quote(dir + "/out.exr");
    const std::vector<std::pair<std::string, std::string>> cases = {
        { "-i " + quote(fifo) + " --denoise -o " + out, "a FIFO" },
        { "-i /dev/zero --denoise -o " + out, "a device" },
        { "-i " + quote(kBox) + " -i:as=variance /dev/zero --cnn -o " + out, "a device" },
        { "-i " + quote(kBox) + " --metrics /dev/zero", "a device" },
        { "-i " + quote(kBox) + " --cnn --heatmap:ref=/dev/zero " + quote(dir + "/h.png"),
          "a device" },
        { "-i " + quote(kBox) + " --cnn:weights=/dev/zero -o " + out, "a device" },
        { "-i " + quote(kBox) + " --cnn:weights=/dev/urandom -o " + out, "a device" },
        { "-i " + quote(kBox) + " --cnn:weights=/proc/self/mem -o " + out,
          "not a mcdenoise weights file" },
        { "-i " + quote(kBox) + " --cnn:weights=" + quote(fifo) + " -o " + out, "a FIFO" },
        { "-i " + quote(kBox) + " --cnn:weights=" + quote(dir) + " -o " + out, "is a folder" },
    };
    for (const auto& [args, message] : cases) {
        mcdn_test::Run run = run_mcdntool(args, "", "timeout 30 ");
        EXPECT_EQ(run.exit_code, 1) << args << ": " << run.output;
        EXPECT_NE(run.output.find(message), std::string::npos) << args << ": " << run.output;
        EXPECT_TRUE(ends_one_line(run)) << run.output;
    }
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.exr"));
    // A recipe whose input is a FIFO, read by mcdntool and by oiiotool through the plugin.
    std::ofstream(dir + "/fifo.mcdn") << "in = fifo.exr\nchain = cnn\n";
    std::ofstream(dir + "/weights.mcdn") << "in = " << kBox << "\ncnn.weights = /dev/zero\n";
    for (const std::string& recipe : { dir + "/fifo.mcdn", dir + "/weights.mcdn" }) {
        mcdn_test::Run run =
            run_mcdntool("-i " + quote(recipe) + " -o " + out,
                         "OIIO_LIBRARY_PATH=" + quote(MCDN_PLUGIN_DIR), "timeout 30 ");
        EXPECT_EQ(run.exit_code, 1) << recipe << ": " << run.output;
        EXPECT_NE(run.output.find("not a regular file"), std::string::npos) << run.output;
        if (has_oiiotool()) {
            run = run_oiiotool(quote(recipe) + " -o " + out);
            EXPECT_NE(run.exit_code, 0) << recipe;
            EXPECT_NE(run.exit_code, 124) << recipe << ": a hang";
            EXPECT_NE(run.output.find("not a regular file"), std::string::npos) << run.output;
        }
    }
}

// An OpenEXR header whose attribute claims more bytes than the file has (a 2 KB file, a
// string of 1.9 GB: OpenEXR would fill that much memory before saying the file ends; the fuzz
// target found two): refused from the header at once, with little memory, the file named.
TEST(RealFiles, AHeaderThatClaimsGigabytesIsRefusedAtOnce)
{
    const std::string dir = temp_dir("real_header");
    std::ifstream box(kBox, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(box)), std::istreambuf_iterator<char>());
    // The first attribute's size (after the magic, the version, its name and type).
    const size_t name_end = bytes.find('\0', 8), type_end = bytes.find('\0', name_end + 1);
    ASSERT_NE(type_end, std::string::npos);
    const uint32_t claimed = 0x6f6c0033;
    for (int b = 0; b < 4; ++b)
        bytes[type_end + 1 + size_t(b)] = char((claimed >> (8 * b)) & 0xff);
    const std::string damaged = dir + "/damaged.exr";
    std::ofstream(damaged, std::ios::binary) << bytes.substr(0, 2048);
    mcdn_test::Run run =
        run_mcdntool("-i " + quote(damaged) + " --denoise -o " + quote(dir + "/out.exr"), "",
                     "timeout 30 /usr/bin/time -f 'rss %M' ");
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find(damaged + ": a damaged OpenEXR header: Attribute '"),
              std::string::npos)
        << run.output;
    EXPECT_NE(run.output.find("type 'string': Invalid size 1869348915"), std::string::npos)
        << run.output;
    const size_t rss = run.output.find("rss ");
    ASSERT_NE(rss, std::string::npos) << run.output;
    EXPECT_LT(std::stol(run.output.substr(rss + 4)), 500000) << run.output;  // KB
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.exr"));
    // Its third attribute claims 1.9 GB, which OpenEXR's core reports, skips and reads on
    // past (it once took 3.8 GB; tests/data/README.md).
    const std::string skipped = test_data("damaged/skipped_attribute.exr");
    run = run_mcdntool("-i " + quote(skipped) + " --denoise -o " + quote(dir + "/out.exr"), "",
                       "timeout 30 /usr/bin/time -f 'rss %M' ");
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find(skipped
                              + ": a damaged OpenEXR header: Attribute 'capDate', type "
                                "'string': Invalid size 1868705555"),
              std::string::npos)
        << run.output;
    const size_t skipped_rss = run.output.find("rss ");
    ASSERT_NE(skipped_rss, std::string::npos) << run.output;
    EXPECT_LT(std::stol(run.output.substr(skipped_rss + 4)), 500000) << run.output;  // KB
    EXPECT_FALSE(OIIO::Filesystem::exists(dir + "/out.exr"));
}

// 7. Half buffers of another render, mirrored, or with a corrupt block: an error naming the
// halves, or (a block) the tile's halves are the render's, said with -v.
TEST(RealFiles, HalvesThatAreNotTheRendersAreCaught)
{
    std::string dir = temp_dir("real_halves");
    const std::string out = quote(dir + "/out.exr");
    // Mirrored halves.
    const std::string flipped_a = dir + "/flipped_A.exr", flipped_b = dir + "/flipped_B.exr";
    ASSERT_TRUE(IBA::flip(read_float(kHalfA)).write(flipped_a));
    ASSERT_TRUE(IBA::flip(read_float(kHalfB)).write(flipped_b));
    // (--denoise without halves in its chain reads none: nothing to check.)
    for (const std::string chain :
         { "--prefilter --nfor", "--prefilter --nfor --sure --mix", "--nfor --sure --mix" }) {
        mcdn_test::Run run =
            run_mcdntool(box_inputs(kBox, flipped_a, flipped_b) + " " + chain + " -o " + out);
        EXPECT_EQ(run.exit_code, 1) << chain << ": " << run.output;
        EXPECT_NE(run.output.find("flipped_A.exr and " + flipped_b), std::string::npos)
            << run.output;
        EXPECT_NE(run.output.find("the halves' mean is not the render"), std::string::npos)
            << run.output;
    }
    // The halves of the reference (another render of the same frame), without a variance file.
    mcdn_test::Run run =
        run_mcdntool("-i " + quote(kBox) + " -i:as=halfA " + quote(kRef) + " -i:as=halfB "
                     + quote(kRef) + " --prefilter --nfor -o " + out);
    EXPECT_EQ(run.exit_code, 1) << run.output;
    // A 3x3 block of 1e6 in halfA alone, in two of the four 32x32 tiles: those tiles' halves
    // are the render, said with -v, each tile once also where bands of rows read it twice
    // (a band's halo is the next band's rows); no value of that size reaches the output.
    OIIO::ImageBuf a = read_float(kHalfA);
    const int r = a.spec().channelindex("ViewLayer.Combined.R");
    for (int y0 : { 8, 40 })
        for (int y = y0; y < y0 + 3; ++y)
            for (int x = 8; x < 11; ++x)
                for (int c = r; c < r + 3; ++c)
                    static_cast<float*>(
                        a.localpixels())[(size_t(y) * a.spec().width + x) * a.nchannels() + c] =
                        1e6f;
    ASSERT_TRUE(a.write(dir + "/block_A.exr"));
    const std::string two_tiles = "mcdntool: 2 tile(s) of 32x32 pixels: the half buffers disagree";
    for (const std::string env : { "", "MCDN_BAND_PIXELS=2048" })
        for (const std::string chain :
             { "--prefilter --nfor", "--prefilter --nfor --sure --mix" }) {
            run = run_mcdntool(
                "-v " + box_inputs(kBox, dir + "/block_A.exr") + " " + chain + " -o " + out, env);
            ASSERT_EQ(run.exit_code, 0) << run.output;
            EXPECT_NE(run.output.find(two_tiles), std::string::npos) << env << run.output;
            EXPECT_NE(run.output.find(env.empty() ? "in 1 band(s)" : "in 2 band(s)"),
                      std::string::npos)
                << run.output;
            OIIO::ImageBuf result = read_float(dir + "/out.exr");
            const OIIO::ImageSpec& s = result.spec();
            const int red = s.channelindex("ViewLayer.Combined.R");
            const IBA::PixelStats stats = IBA::computePixelStats(
                result, OIIO::ROI(s.x, s.x + s.width, s.y, s.y + s.height, 0, 1, red, red + 3));
            for (float v : stats.max)
                EXPECT_LT(v, 100.0f) << chain;
        }
    // The OIIO plugin says them on its image, in bands too.
    if (has_oiiotool())
        for (const std::string env : { "", "MCDN_BAND_PIXELS=2048" }) {
            run = run_oiiotool(quote("s.mcdn?in=" + kBox + "&variance=" + kVar + "&halfA=" + dir
                                     + "/block_A.exr&halfB=" + kHalfB + "&chain=prefilter,nfor")
                                   + " --printinfo:verbose=1",
                               env);
            ASSERT_EQ(run.exit_code, 0) << run.output;
            EXPECT_NE(run.output.find("mcdn:halves_repaired: 2\n"), std::string::npos)
                << env << run.output;
        }
}

// 9. Values no stage can take are refused, in every channel a stage reads; pass-through
// channels are written as they came.
TEST(RealFiles, HugeValuesAndLongNormalsAreRefused)
{
    std::string dir = temp_dir("real_huge");
    auto edited = [&](const std::string& name, const std::string& channel, float value) {
        OIIO::ImageBuf box = read_float(kBox);
        const int c = box.spec().channelindex(channel);
        EXPECT_GE(c, 0) << channel;
        float* pixels = static_cast<float*>(box.localpixels());
        pixels[(size_t(5) * box.spec().width + 7) * box.nchannels() + c] = value;
        const std::string path = dir + "/" + name;
        EXPECT_TRUE(box.write(path));
        return path;
    };
    const std::string color = edited("colour.exr", "ViewLayer.Combined.G", 1e16f);
    mcdn_test::Run run = run_mcdntool("-i " + quote(color) + " --cnn -o " + quote(dir + "/o.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("channel 'ViewLayer.Combined.G' (role color) has a huge value"),
              std::string::npos)
        << run.output;
    run = run_mcdntool("-i " + quote(edited("normal.exr", "ViewLayer.Denoising Normal.X", 1e10f))
                       + " --cnn -o " + quote(dir + "/o.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("a normal of length 1e+10 at pixel (7, 5)"), std::string::npos)
        << run.output;
    // Depth.Z (no stage reads it) keeps 1e18 as it is.
    const std::string depth = edited("depth.exr", "ViewLayer.Depth.Z", 1e18f);
    run = run_mcdntool("-i " + quote(depth) + " --cnn -o " + quote(dir + "/o.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    OIIO::ImageBuf o = read_float(dir + "/o.exr");
    float v = 0;
    o.getpixel(7, 5, 0, &v, 0);
    std::vector<float> px(o.nchannels());
    o.getpixel(7, 5, px.data(), o.nchannels());
    EXPECT_EQ(px[o.spec().channelindex("ViewLayer.Depth.Z")], 1e18f);
}

// 10. A temporary's PID means something only on its own host and PID namespace: another
// node's (or container's) temporary is never removed while it may be written.
TEST(RealFiles, AnotherHostsTemporaryIsNotRemoved)
{
    std::string dir = temp_dir("real_farm");
    const std::string prefix = dir + "/.out.exr.mcdn-tmp-";
    const std::string ours_dead = prefix + "99999999-0-" + mcdn::temporary_owner();
    const std::string other_host = prefix + "99999999-0-4026531836-othernode";
    const std::string other_ns =
        prefix + "99999999-3-1234-"
        + mcdn::temporary_owner().substr(mcdn::temporary_owner().find('-') + 1);
    const std::string old_style = prefix + "99999999-0";
    const std::string other_old = prefix + "99999999-1-4026531836-othernode";
    for (const auto& f : { ours_dead, other_host, other_ns, old_style, other_old })
        std::ofstream(f) << "partial";
    // Not written for two days: nobody writes it.
    const std::string touch = "touch -d '2 days ago' " + quote(other_old);
    ASSERT_EQ(std::system(touch.c_str()), 0);
    mcdn_test::Run run = run_mcdntool("-i " + quote(kBox) + " -o " + quote(dir + "/out.exr"));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_FALSE(OIIO::Filesystem::exists(ours_dead));
    EXPECT_TRUE(OIIO::Filesystem::exists(other_host));
    EXPECT_TRUE(OIIO::Filesystem::exists(other_ns));
    EXPECT_TRUE(OIIO::Filesystem::exists(old_style));
    EXPECT_FALSE(OIIO::Filesystem::exists(other_old));
    // The race itself: a writer in another PID namespace (unshare, where it may run) is
    // still writing when a requeued run here writes the same output; it must finish.
    if (std::system("unshare --pid --fork --mount-proc true 2>/dev/null") != 0)
        return;
    OIIO::ImageBuf big = IBA::resize(read_float(kBox), "", 0.0f, OIIO::ROI(0, 512, 0, 512));
    ASSERT_TRUE(big.write(dir + "/big.exr"));
    const std::string first =
        "MCDN_BAND_PIXELS=16384 unshare --pid --fork --mount-proc '" + std::string(MCDNTOOL)
        + "' -i " + quote(dir + "/big.exr") + " --cnn -o " + quote(dir + "/race.exr") + " > "
        + quote(dir + "/first.log") + " 2>&1; echo $? > " + quote(dir + "/first.rc.part")
        + " && mv " + quote(dir + "/first.rc.part") + " " + quote(dir + "/first.rc");
    ASSERT_EQ(std::system(("(" + first + ") &").c_str()), 0);
    // Generous bounds: under ASan, with the other tests on two cores, the first writer's
    // CNN takes minutes; both loops end as soon as what they wait for is there.
    bool seen = false;
    for (int i = 0; i < 12000 && !seen; ++i) {
        for (const auto& e : std::filesystem::directory_iterator(dir))
            seen |= e.path().filename().string().rfind(".race.exr.mcdn-tmp-", 0) == 0;
        if (!seen)
            ::usleep(10000);
    }
    ASSERT_TRUE(seen) << "the first writer's temporary never appeared";
    run = run_mcdntool("-i " + quote(dir + "/big.exr") + " -o " + quote(dir + "/race.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    for (int i = 0; i < 60000 && !OIIO::Filesystem::exists(dir + "/first.rc"); ++i)
        ::usleep(10000);
    std::ifstream rc(dir + "/first.rc");
    int code = -1;
    rc >> code;
    std::ifstream log(dir + "/first.log");
    EXPECT_EQ(code, 0) << std::string(std::istreambuf_iterator<char>(log), {});
}

// 11. The plugin: a recipe read again after it or its input changed gives the new result,
// and results nobody holds are freed.
TEST(RealFiles, ThePluginSeesChangedFiles)
{
    if (system("/usr/bin/python3 -c 'import OpenImageIO' 2>/dev/null") != 0)
        GTEST_SKIP() << "python3-openimageio not installed";
    std::string dir = temp_dir("real_plugin_cache");
    // 256x256: a result the cache kept for every recipe would add 10 MB a recipe.
    const std::string render = dir + "/render.exr";
    ASSERT_TRUE(IBA::resize(read_float(kBox), "", 0.0f, OIIO::ROI(0, 256, 0, 256)).write(render));
    std::ofstream(dir + "/shot.mcdn") << "in = render.exr\nchain = cnn\n";
    const std::string script = dir + "/cache.py";
    std::ofstream(script) << R"(import os, sys, resource
import OpenImageIO as oiio
d = sys.argv[1]
recipe = os.path.join(d, "shot.mcdn")
def first():
    buf = oiio.ImageBuf(recipe)
    buf.read(0, 0, True, oiio.FLOAT)
    assert not buf.has_error, buf.geterror()
    return buf.getpixel(10, 10)[0]
before = first()
buf = oiio.ImageBuf(os.path.join(d, "render.exr"))
buf = oiio.ImageBufAlgo.mul(buf, tuple(2.0 if "Combined" in n else 1.0
                                        for n in buf.spec().channelnames))
buf.write(os.path.join(d, "render2.exr"))
os.replace(os.path.join(d, "render2.exr"), os.path.join(d, "render.exr"))
oiio.ImageCache(True).invalidate_all(True)
after = first()
print("before", before, "after", after)
assert after > 1.5 * before, (before, after)  # the render doubled: not the old pixels
with open(recipe, "a") as f:
    f.write("colour = 1\n")
buf = oiio.ImageBuf(recipe)
buf.read(0, 0, True, oiio.FLOAT)
assert buf.has_error and "unknown key 'colour'" in buf.geterror(), buf.geterror()
# Many distinct recipes: memory stays bounded.
rss = []
for i in range(16):
    buf = oiio.ImageBuf(os.path.join(d, "x.mcdn?in=render.exr&chain=cnn&sure.probes=%d" % (1 + i)))
    buf.read(0, 0, True, oiio.FLOAT)
    del buf
    oiio.ImageCache(True).invalidate_all(True)
    rss.append(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)
print("rss", rss[4], rss[-1])
assert rss[-1] - rss[4] < 50 * 1024, rss
)";
    mcdn_test::Run run =
        run_command("cd " + quote(dir) + " && OIIO_LIBRARY_PATH=" + quote(MCDN_PLUGIN_DIR)
                    + " /usr/bin/python3 " + quote(script) + " " + quote(dir));
    EXPECT_EQ(run.exit_code, 0) << run.output;
}

// 12, 13. mcdntool reading a recipe says the recipe's error; a recipe that is another file
// (a symlink) never has that file's values echoed.
TEST(RealFiles, RecipeErrorsAreTheRecipesAndQuoteNoValues)
{
    std::string dir = temp_dir("real_recipe_errors");
    const std::string env = "OIIO_LIBRARY_PATH=" + quote(MCDN_PLUGIN_DIR);
    std::ofstream(dir + "/bad.mcdn") << "in = nothere.exr\n";
    mcdn_test::Run run = run_mcdntool("-i " + quote(dir + "/bad.mcdn") + " --info", env);
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("nothere.exr: no such file"), std::string::npos) << run.output;
    EXPECT_EQ(run.output.find("mcdn_error"), std::string::npos) << run.output;
    std::ofstream(dir + "/secrets.conf") << "in = " << kBox << "\naws.key=AKIASECRETVALUE\n";
    ASSERT_EQ(::symlink((dir + "/secrets.conf").c_str(), (dir + "/leak.mcdn").c_str()), 0);
    for (const std::string& how : { std::string("-i ") + quote(dir + "/leak.mcdn") + " --info" }) {
        run = run_mcdntool(how, env);
        EXPECT_EQ(run.exit_code, 1) << run.output;
        EXPECT_EQ(run.output.find("AKIASECRETVALUE"), std::string::npos) << run.output;
        EXPECT_NE(run.output.find("'aws.key'"), std::string::npos) << run.output;
    }
    if (has_oiiotool()) {
        run = run_oiiotool(quote(dir + "/leak.mcdn") + " -o " + quote(dir + "/o.exr"));
        EXPECT_NE(run.exit_code, 0);
        EXPECT_EQ(run.output.find("AKIASECRETVALUE"), std::string::npos) << run.output;
        // A recipe that does not parse says why, not "File does not exist".
        std::ofstream(dir + "/broken.mcdn") << "in = " << kBox << "\nnot a setting\n";
        run = run_oiiotool(quote(dir + "/broken.mcdn") + " -o " + quote(dir + "/q.exr"));
        EXPECT_NE(run.output.find("broken.mcdn:2: expected key = value"), std::string::npos)
            << run.output;
    }
}

// The smaller items: the output's mode, read-only outputs as root, mixed padding, oiiotool's
// compression levels, which file's channels an error lists, --fixnan error, one "cnn:",
// two frame patterns in one name.
TEST(RealFiles, TheSmallerItems)
{
    std::string dir = temp_dir("real_small");
    const std::string out = dir + "/out.exr";
    // The mode of a replaced output is kept.
    std::ofstream(out) << "old";
    ASSERT_EQ(::chmod(out.c_str(), 0600), 0);
    mcdn_test::Run run = run_mcdntool("-i " + quote(kBox) + " -o " + quote(out));
    ASSERT_EQ(run.exit_code, 0) << run.output;
    struct stat st;
    ASSERT_EQ(::stat(out.c_str(), &st), 0);
    EXPECT_EQ(st.st_mode & 07777, 0600u);
    // A read-only output is not replaced, even by root.
    ASSERT_EQ(::chmod(out.c_str(), 0444), 0);
    run = run_mcdntool("-i " + quote(kBox) + " -o " + quote(out));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    // (root's message; a user's: "cannot be written")
    EXPECT_TRUE(run.output.find("read-only (mode 0444)") != std::string::npos
                || (::geteuid() != 0 && run.output.find("cannot be written") != std::string::npos))
        << run.output;
    ::chmod(out.c_str(), 0644);
    // oiiotool's compression=zip:5 and dwaa:45 are levels, not modifiers.
    for (const std::string c : { "zip:5", "dwaa:45" }) {
        run = run_mcdntool("-i " + quote(kBox) + " -o:compression=" + c + " " + quote(out));
        EXPECT_EQ(run.exit_code, 0) << c << ": " << run.output;
        auto in = OIIO::ImageInput::open(out);
        ASSERT_TRUE(in);
        // OpenEXR keeps dwaa's level in the file, not zip's.
        EXPECT_EQ(in->spec().get_string_attribute("compression"), c.substr(0, c.find(':')));
    }
    // A variance file without the colour's variance lists its own channels, not the render's.
    OIIO::ImageBuf odd =
        make_image(64, 64, { "V.R", "V.G", "V.B" }, [](int, int, int) { return 0.01f; });
    ASSERT_TRUE(odd.write(dir + "/odd_var.exr"));
    run = run_mcdntool("-i " + quote(kBox) + " -i:as=variance " + quote(dir + "/odd_var.exr")
                       + " --cnn -o " + quote(out));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("channels there: variance.V.R,variance.V.G,variance.V.B;"),
              std::string::npos)
        << run.output;
    // --fixnan error names the channel.
    OIIO::ImageBuf nan = read_float(kBox);
    const int depth = nan.spec().channelindex("ViewLayer.Depth.Z");
    static_cast<float*>(nan.localpixels())[(size_t(3) * 64 + 4) * nan.nchannels() + depth] = NAN;
    ASSERT_TRUE(nan.write(dir + "/nan.exr"));
    run = run_mcdntool("-i " + quote(dir + "/nan.exr") + " --fixnan error -o " + quote(out));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("channel 'ViewLayer.Depth.Z' has NaN at pixel (4, 3)"),
              std::string::npos)
        << run.output;
    // A NaN in the beauty stops the frame naming --fixnan; --fixnan box3 right after the
    // inputs repairs it as it is read, and the frame is denoised (issue 46, item 8).
    OIIO::ImageBuf nan_beauty = read_float(kBox);
    const int red = nan_beauty.spec().channelindex("ViewLayer.Combined.R");
    static_cast<float*>(
        nan_beauty.localpixels())[(size_t(7) * 64 + 9) * nan_beauty.nchannels() + red] = NAN;
    ASSERT_TRUE(nan_beauty.write(dir + "/nan_beauty.exr"));
    run = run_mcdntool("-i " + quote(dir + "/nan_beauty.exr") + " --denoise -o " + quote(out));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("has NaN at pixel (9, 7)"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("--fixnan box3"), std::string::npos) << run.output;
    run = run_mcdntool("-v -i " + quote(dir + "/nan_beauty.exr") + " --fixnan box3 --denoise -o "
                       + quote(out));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("fixnan box3: 1 pixels repaired"), std::string::npos) << run.output;
    {
        OIIO::ImageBuf repaired(out);
        ASSERT_TRUE(repaired.read(0, 0, true, OIIO::TypeFloat));
        EXPECT_TRUE(OIIO::ImageBufAlgo::computePixelStats(repaired).nancount[0] == 0);
        EXPECT_TRUE(std::isfinite(repaired.getchannel(9, 7, 0, red)));
    }
    // Blender's and Nuke's padding: '#' is oiiotool's 4 digits here, and the error says what
    // to type (issue 46, item 9).
    ASSERT_TRUE(OIIO::Filesystem::copy(kBox, dir + "/seq.0001.exr"));
    run = run_mcdntool("-i " + quote(dir + "/seq.####.exr") + " --cnn -o "
                       + quote(dir + "/o.####.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("Blender's and Nuke's shot.####.exr is shot.#.exr"),
              std::string::npos)
        << run.output;
    // The output's folder is made (mkdir -p); a file where a folder should be is refused.
    run = run_mcdntool("-i " + quote(kBox) + " --cnn -o " + quote(dir + "/new/sub/o.exr"));
    EXPECT_EQ(run.exit_code, 0) << run.output;
    EXPECT_TRUE(OIIO::Filesystem::exists(dir + "/new/sub/o.exr"));
    run = run_mcdntool("-i " + quote(kBox) + " --cnn -o " + quote(dir + "/seq.0001.exr/o.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("is not a folder"), std::string::npos) << run.output;
    // After a bad frame the count goes on from it: frame 3 is the 3rd of 3.
    ASSERT_TRUE(OIIO::Filesystem::copy(kBox, dir + "/seq.0003.exr"));
    OIIO::Filesystem::write_text_file(dir + "/seq.0002.exr", "not an image");
    run = run_mcdntool("--skip-bad-frames -i " + quote(dir + "/seq.#.exr") + " --cnn -o "
                       + quote(dir + "/o.#.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("frame 2 (2/3): "), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("frame 3 (3/3) done"), std::string::npos) << run.output;
    // The stage named once.
    run = run_mcdntool("-i " + quote(kBox) + " --cnn:weights=" + quote(kBox) + " -o " + quote(out));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_EQ(run.output.find("cnn: cnn:"), std::string::npos) << run.output;
    // Two frame patterns in one name.
    run = run_mcdntool("-i " + quote(kBox) + " -o " + quote(dir + "/o.%04d.%04d.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("2 frame patterns in one name"), std::string::npos) << run.output;
    // A luminance/chroma file (RY and BY subsampled 2x2, as OpenEXR's RgbaOutputFile writes
    // WRITE_YC): OIIO cannot read it; the one error line names the file. OIIO writes no
    // subsampled channel: its header's sampling is set afterwards.
    {
        OIIO::ImageSpec yc(4, 4, 3, OIIO::TypeDesc::HALF);
        yc.channelnames = { "BY", "RY", "Y" };
        yc.attribute("compression", "none");
        ASSERT_TRUE(OIIO::ImageBuf(yc).write(dir + "/yc.exr"));
        std::ifstream in(dir + "/yc.exr", std::ios::binary);
        std::string bytes(std::istreambuf_iterator<char>(in), {});
        const std::string chlist("channels\0chlist\0", 16);  // the attribute's name, type
        const size_t list = bytes.find(chlist);
        ASSERT_NE(list, std::string::npos);
        for (const std::string name : { "BY", "RY" }) {
            // name\0, pixel type (4), pLinear and reserved (4), xSampling (4), ySampling (4)
            const size_t at = bytes.find(name + '\0', list + chlist.size()) + name.size() + 9;
            bytes[at] = bytes[at + 4] = 2;
        }
        std::ofstream(dir + "/yc.exr", std::ios::binary) << bytes;
        run = run_mcdntool("-i " + quote(dir + "/yc.exr") + " --denoise -o " + quote(out));
        EXPECT_EQ(run.exit_code, 1) << run.output;
        EXPECT_NE(run.output.find("yc.exr: cannot read: Subsampled channels are not supported"),
                  std::string::npos)
            << run.output;
        EXPECT_TRUE(ends_one_line(run)) << run.output;
    }
    // shot.1.exr and shot.0001.exr are both frame 1 of shot.@.exr: an error, not frame 1 twice.
    ASSERT_EQ(std::system(("cp " + quote(kBox) + " " + quote(dir + "/shot.1.exr") + " && cp "
                           + quote(kBox) + " " + quote(dir + "/shot.0001.exr"))
                              .c_str()),
              0);
    run = run_mcdntool("-i " + quote(dir + "/shot.@.exr") + " -o " + quote(dir + "/o.@.exr"));
    EXPECT_EQ(run.exit_code, 1) << run.output;
    EXPECT_NE(run.output.find("are both frame 1"), std::string::npos) << run.output;
}

// 3. Out of memory inside any chain is a one-line error and exit 1, never a crash: each
// chain on a 1024x1024 frame under three address-space limits (it fails at different steps;
// under 1400000 kB --cnn once crashed inside oneDNN as it made a kernel).
TEST(RealFiles, OutOfMemoryInEveryChainIsAnError)
{
    std::string dir = temp_dir("real_oom");
    std::string inputs;
    for (const auto& [file, as] :
         { std::pair { kBox, "" }, std::pair { kVar, ":as=variance" },
           std::pair { kHalfA, ":as=halfA" }, std::pair { kHalfB, ":as=halfB" } }) {
        const std::string big = dir + "/" + OIIO::Filesystem::filename(file);
        OIIO::ImageBuf resized =
            IBA::resize(read_float(file), "", 0.0f, OIIO::ROI(0, 1024, 0, 1024));
        ASSERT_TRUE(resized.write(big));
        inputs += " -i" + std::string(as) + " " + quote(big);
    }
    for (const std::string chain :
         { "--denoise", "--cnn", "--prefilter --nfor", "--prefilter --nfor --sure --mix",
           "--cnn --sure --mix", "--nfor --sure --mix:model=analytic" })
        for (const char* limit : { "1572864", "1400000", "900000" }) {
            mcdn_test::Run run =
                run_command("ulimit -v " + std::string(limit) + "; '" + MCDNTOOL + "'" + inputs
                            + " " + chain + " -o " + quote(dir + "/out.exr"));
            EXPECT_TRUE(run.exit_code == 0 || run.exit_code == 1)
                << chain << " under " << limit << " kB: exit " << run.exit_code << ": "
                << run.output;
            if (run.exit_code == 1) {
                EXPECT_NE(run.output.find("out of memory"), std::string::npos) << run.output;
                EXPECT_TRUE(ends_one_line(run)) << run.output;
            }
            EXPECT_TRUE(std::none_of(std::filesystem::directory_iterator(dir),
                                     std::filesystem::directory_iterator(), [](const auto& e) {
                                         return e.path().filename().string().find("mcdn-tmp")
                                                != std::string::npos;
                                     }));
        }
}
