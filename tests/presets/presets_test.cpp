// Files named as each renderer writes them, made from our Cycles render (tests/data/box16),
// denoised with `mcdntool -i FILE --denoise -o OUT` and no other flag: the preset is detected,
// the chain picked, and the result is closer to the reference than the render is.
#include <map>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>

#include "mcdn/aov.h"
#include "mcdn/metrics.h"

#include "mcdn_test.h"

namespace {

using mcdn_test::run_mcdntool;
using mcdn_test::test_data;
using OIIO::ImageBuf;
using OIIO::ImageBufAlgo::channels;

const std::string kBox = "box16/box_0016spp";

ImageBuf read(const std::string& rel)
{
    ImageBuf b(test_data(rel));
    EXPECT_TRUE(b.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << b.geterror();
    return b;
}

/// One renderer channel: its name, and the box16 file and channel it is made of.
struct Source {
    std::string name;
    std::string file;  // "" (the render), "_var", "_A", "_B"
    std::string channel;
};

/// A file whose channels are the sources, in order; ops on the channels (diffuse/specular)
/// are done by the caller through `extra`.
ImageBuf assemble(const std::vector<Source>& sources,
                  const std::vector<std::pair<std::string, ImageBuf>>& extra = {})
{
    std::map<std::string, ImageBuf> files;
    for (const char* f : { "", "_var", "_A", "_B" })
        files[f] = read(kBox + f + ".exr");
    ImageBuf out;
    std::vector<std::string> names;
    for (const Source& s : sources) {
        const ImageBuf& from = files[s.file];
        int c = from.spec().channelindex(s.channel);
        EXPECT_GE(c, 0) << s.channel;
        ImageBuf one = channels(from, 1, { c });
        out = out.initialized() ? OIIO::ImageBufAlgo::channel_append(out, one) : one;
        names.push_back(s.name);
    }
    for (const auto& [name, plane] : extra) {
        out = OIIO::ImageBufAlgo::channel_append(out, plane);
        names.push_back(name);
    }
    out.specmod().channelnames = names;
    out.specmod().alpha_channel = -1;
    out.specmod().z_channel = -1;
    return out;
}

std::vector<Source> rgb(const std::vector<std::string>& names, const std::string& file,
                        const std::string& stem, const char* suffixes = "RGB")
{
    std::vector<Source> out;
    for (int i = 0; i < 3; ++i)
        out.push_back({ names[i], file, "ViewLayer." + stem + "." + suffixes[i] });
    return out;
}

std::vector<Source> concat(std::initializer_list<std::vector<Source>> parts)
{
    std::vector<Source> out;
    for (const auto& p : parts)
        out.insert(out.end(), p.begin(), p.end());
    return out;
}

double relmse(const ImageBuf& image, const std::vector<std::string>& color)
{
    ImageBuf reference = read("box16/box_ref.exr");
    mcdn::MetricsOptions o;
    o.image_channels.clear();
    for (const auto& c : color)
        o.image_channels.push_back(image.spec().channelindex(c));
    o.reference_channels = { reference.spec().channelindex("ViewLayer.Combined.R"),
                             reference.spec().channelindex("ViewLayer.Combined.G"),
                             reference.spec().channelindex("ViewLayer.Combined.B") };
    mcdn::Metrics m;
    std::string error;
    EXPECT_TRUE(mcdn::compute_metrics(m, image, reference, o, error)) << error;
    return m.relmse;
}

/// Writes `file`, denoises it with --denoise alone, and checks the detected preset, the
/// chain picked and the error against the render's.
void denoises_below_the_render(const std::string& name, const ImageBuf& file,
                               const std::vector<std::string>& color, const std::string& preset,
                               const std::string& chain)
{
    const std::string dir = mcdn_test::temp_dir("presets_" + name);
    ASSERT_TRUE(file.write(dir + "/beauty.exr")) << file.geterror();
    auto run = run_mcdntool("-v -i " + dir + "/beauty.exr --denoise -o " + dir + "/out.exr");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("AOV preset '" + preset + "'"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("--denoise runs " + chain + ":"), std::string::npos) << run.output;
    ImageBuf written(dir + "/beauty.exr"), out(dir + "/out.exr");
    ASSERT_TRUE(out.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << out.geterror();
    ASSERT_TRUE(written.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << written.geterror();
    EXPECT_EQ(out.spec().channelnames, written.spec().channelnames) << "channels kept";
    const double render = relmse(written, color), denoised = relmse(out, color);
    EXPECT_LT(denoised, 0.5 * render) << name << ": render " << render << ", denoised " << denoised;
}

const std::vector<std::string> kRGB = { "R", "G", "B" };

// Arnold: beauty R,G,B (Preserve Layer Name off), its variance_filter output `variance`, N,
// Z, denoise_albedo (help.autodesk.com, Arnold User Guide: Arnold Denoiser, AOVs).
TEST(Presets, ArnoldBeautyWithVarianceRunsTheMixedChain)
{
    ImageBuf file =
        assemble(concat({ rgb(kRGB, "", "Combined"),
                          rgb({ "variance.R", "variance.G", "variance.B" }, "_var", "Combined"),
                          rgb({ "N.X", "N.Y", "N.Z" }, "", "Denoising Normal", "XYZ"),
                          { { "Z", "", "ViewLayer.Denoising Depth.Z" } },
                          rgb({ "denoise_albedo.R", "denoise_albedo.G", "denoise_albedo.B" }, "",
                              "Denoising Albedo") }));
    denoises_below_the_render("arnold", file, kRGB, "arnold", "cnn -> sure -> mix (net)");
}

// Arnold's diffuse and specular AOVs are the CNN's light split (§4.3): the diffuse divided
// by the albedo, the rest of the beauty specular. Made from box16's Blender passes
// (diffuse = DiffCol * (DiffDir + DiffInd)); the split's result is closer to the reference.
TEST(Presets, ArnoldDiffuseAndSpecularAreTheSplit)
{
    const std::vector<Source> base =
        concat({ rgb(kRGB, "", "Combined"),
                 rgb({ "variance.R", "variance.G", "variance.B" }, "_var", "Combined"),
                 rgb({ "N.X", "N.Y", "N.Z" }, "", "Denoising Normal", "XYZ"),
                 { { "Z", "", "ViewLayer.Denoising Depth.Z" } },
                 rgb({ "denoise_albedo.R", "denoise_albedo.G", "denoise_albedo.B" }, "",
                     "Denoising Albedo") });
    const ImageBuf render = read(kBox + ".exr");
    auto plane = [&](const std::string& pass, const char* c) {
        return channels(render, 1, { render.spec().channelindex("ViewLayer." + pass + "." + c) });
    };
    std::vector<std::pair<std::string, ImageBuf>> split;
    for (const char* part : { "diffuse", "specular" })
        for (const char* c : { "R", "G", "B" }) {
            ImageBuf diffuse = OIIO::ImageBufAlgo::mul(
                plane("DiffCol", c),
                OIIO::ImageBufAlgo::add(plane("DiffDir", c), plane("DiffInd", c)));
            split.push_back({ std::string(part) + "." + c,
                              std::string(part) == "diffuse"
                                  ? diffuse
                                  : OIIO::ImageBufAlgo::sub(plane("Combined", c), diffuse) });
        }
    const std::string dir = mcdn_test::temp_dir("presets_arnold_split");
    double error[2] = {};
    for (int with = 0; with < 2; ++with) {
        const ImageBuf file = with ? assemble(base, split) : assemble(base);
        const std::string in = dir + "/in" + std::to_string(with) + ".exr";
        const std::string out = dir + "/out" + std::to_string(with) + ".exr";
        ASSERT_TRUE(file.write(in)) << file.geterror();
        auto run = run_mcdntool("-i " + in + " --info");
        ASSERT_EQ(run.exit_code, 0) << run.output;
        EXPECT_EQ(run.output.find("diffuse.R, diffuse.G, diffuse.B") != std::string::npos,
                  bool(with))
            << run.output;
        run = run_mcdntool("-i " + in + " --denoise -o " + out);
        ASSERT_EQ(run.exit_code, 0) << run.output;
        ImageBuf denoised(out);
        ASSERT_TRUE(denoised.read(0, 0, true, OIIO::TypeDesc::FLOAT));
        error[with] = relmse(denoised, kRGB);
        if (!with)
            continue;
        // Arnold's light AOVs are denoised with the beauty, and still add up to it.
        double residual = 0, beauty = 0, moved = 0;
        const OIIO::ImageSpec& s = denoised.spec();
        for (int y = 0; y < s.height; ++y)
            for (int x = 0; x < s.width; ++x)
                for (const char* c : { "R", "G", "B" }) {
                    auto at = [&](const ImageBuf& b, const std::string& name) {
                        return b.getchannel(x, y, 0, b.spec().channelindex(name));
                    };
                    const double sum = at(denoised, std::string("diffuse.") + c)
                                       + at(denoised, std::string("specular.") + c);
                    residual += std::abs(sum - at(denoised, c));
                    beauty += std::abs(at(denoised, c));
                    moved += std::abs(at(denoised, std::string("diffuse.") + c)
                                      - at(file, std::string("diffuse.") + c));
                }
        EXPECT_LT(residual / beauty, 1e-4);
        EXPECT_GT(moved / (3.0 * s.width * s.height), 1e-3) << "the diffuse AOV is denoised";
    }
    // Measured: 0.0213 without the split, 0.0195 with it.
    EXPECT_LT(error[1], 0.95 * error[0]) << error[0] << " -> " << error[1];
}

// Arnold with Preserve Layer Name on: RGBA.R, ...
TEST(Presets, ArnoldLayerNamesAreDetected)
{
    const std::vector<std::string> color = { "RGBA.R", "RGBA.G", "RGBA.B" };
    ImageBuf file =
        assemble(concat({ rgb(color, "", "Combined"),
                          rgb({ "variance.R", "variance.G", "variance.B" }, "_var", "Combined"),
                          rgb({ "N.R", "N.G", "N.B" }, "", "Denoising Normal", "XYZ"),
                          rgb({ "albedo.R", "albedo.G", "albedo.B" }, "", "Denoising Albedo") }));
    denoises_below_the_render("arnold_layers", file, color, "arnold", "cnn -> sure -> mix (net)");
}

// RenderMan's denoise outputs: Ci, mse, albedo(_var), normal(_var), zfiltered(_var)
// (rmanwiki.pixar.com: Denoising).
TEST(Presets, RenderManDenoiseChannelsRunTheMixedChain)
{
    const std::vector<std::string> color = { "Ci.r", "Ci.g", "Ci.b" };
    ImageBuf file = assemble(concat(
        { rgb(color, "", "Combined"),
          rgb({ "mse.r", "mse.g", "mse.b" }, "_var", "Combined"),
          rgb({ "albedo.r", "albedo.g", "albedo.b" }, "", "Denoising Albedo"),
          rgb({ "albedo_var.r", "albedo_var.g", "albedo_var.b" }, "_var", "Denoising Albedo"),
          rgb({ "normal.x", "normal.y", "normal.z" }, "", "Denoising Normal", "XYZ"),
          rgb({ "normal_var.x", "normal_var.y", "normal_var.z" }, "_var", "Denoising Normal",
              "XYZ"),
          { { "zfiltered", "", "ViewLayer.Denoising Depth.Z" },
            { "zfiltered_var", "_var", "ViewLayer.Denoising Depth.Z" } } }));
    denoises_below_the_render("renderman", file, color, "renderman", "cnn -> sure -> mix (net)");
}

// What OIDN needs (and many Blender users have): the beauty with albedo and normal.
TEST(Presets, BeautyAlbedoNormalOnlyRunsTheCnn)
{
    ImageBuf file = assemble(
        concat({ rgb(kRGB, "", "Combined"),
                 rgb({ "albedo.R", "albedo.G", "albedo.B" }, "", "Denoising Albedo"),
                 rgb({ "normal.X", "normal.Y", "normal.Z" }, "", "Denoising Normal", "XYZ") }));
    denoises_below_the_render("oidn", file, kRGB, "oidn", "cnn");
}

// A luminance-only file (OpenEXR's Y; oiiotool --ch writes one): denoised as grey, exactly
// as the file with R = G = B = Y is, and below its render's error (issue 46, item 6;
// before: "role 'color' not found").
TEST(Presets, LuminanceOnlyFileIsDenoisedAsGrey)
{
    const auto luminance = [](const ImageBuf& rgb_image, const char* stem) {
        const OIIO::ImageSpec& spec = rgb_image.spec();
        ImageBuf three = channels(rgb_image, 3,
                                  { spec.channelindex(std::string(stem) + ".R"),
                                    spec.channelindex(std::string(stem) + ".G"),
                                    spec.channelindex(std::string(stem) + ".B") });
        const float weights[] = { 0.2126f, 0.7152f, 0.0722f };
        return OIIO::ImageBufAlgo::channel_sum(three, weights);
    };
    const ImageBuf y = luminance(read(kBox + ".exr"), "ViewLayer.Combined");
    const std::vector<Source> features =
        concat({ rgb({ "albedo.R", "albedo.G", "albedo.B" }, "", "Denoising Albedo"),
                 rgb({ "N.X", "N.Y", "N.Z" }, "", "Denoising Normal", "XYZ") });
    const std::string dir = mcdn_test::temp_dir("presets_luminance");
    const ImageBuf grey_file = assemble(features, { { "R", y }, { "G", y }, { "B", y } });
    const ImageBuf y_file = assemble(features, { { "Y", y } });
    ASSERT_TRUE(grey_file.write(dir + "/grey.exr")) << grey_file.geterror();
    ASSERT_TRUE(y_file.write(dir + "/y.exr")) << y_file.geterror();
    auto run = run_mcdntool("-i " + dir + "/grey.exr --denoise -o " + dir + "/grey_out.exr");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    run = run_mcdntool("-v -i " + dir + "/y.exr --denoise -o " + dir + "/y_out.exr");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("luminance only (Y): denoised as grey"), std::string::npos)
        << run.output;
    ImageBuf grey_out(dir + "/grey_out.exr"), y_out(dir + "/y_out.exr");
    ASSERT_TRUE(grey_out.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << grey_out.geterror();
    ASSERT_TRUE(y_out.read(0, 0, true, OIIO::TypeDesc::FLOAT)) << y_out.geterror();
    const int yc = y_out.spec().channelindex("Y"), g = grey_out.spec().channelindex("G");
    ASSERT_GE(yc, 0);
    for (int py = 0; py < y.spec().height; ++py)
        for (int px = 0; px < y.spec().width; ++px)
            ASSERT_EQ(y_out.getchannel(px, py, 0, yc), grey_out.getchannel(px, py, 0, g));
    // The error of the luminance against the reference's.
    const ImageBuf y_ref = luminance(read("box16/box_ref.exr"), "ViewLayer.Combined");
    const auto error = [&](const ImageBuf& image) {
        mcdn::MetricsOptions o;
        const int c = image.spec().channelindex("Y");
        o.image_channels = { c, c, c };
        o.reference_channels = { 0, 0, 0 };
        mcdn::Metrics m;
        std::string why;
        EXPECT_TRUE(mcdn::compute_metrics(m, image, y_ref, o, why)) << why;
        return m.relmse;
    };
    ImageBuf written(dir + "/y.exr");
    ASSERT_TRUE(written.read(0, 0, true, OIIO::TypeDesc::FLOAT));
    EXPECT_LT(error(y_out), 0.5 * error(written)) << error(written) << " -> " << error(y_out);
}

// Blender's own names, beauty with Denoising Albedo/Normal only (no variance, no halves).
TEST(Presets, CyclesBeautyWithDenoisingPassesRunsTheCnn)
{
    const std::vector<std::string> color = { "ViewLayer.Combined.R", "ViewLayer.Combined.G",
                                             "ViewLayer.Combined.B" };
    std::vector<Source> s = rgb(color, "", "Combined");
    for (const char* c : { "R", "G", "B" })
        s.push_back({ std::string("ViewLayer.Denoising Albedo.") + c, "",
                      std::string("ViewLayer.Denoising Albedo.") + c });
    for (const char* c : { "X", "Y", "Z" })
        s.push_back({ std::string("ViewLayer.Denoising Normal.") + c, "",
                      std::string("ViewLayer.Denoising Normal.") + c });
    denoises_below_the_render("cycles_oidn", assemble(s), color, "cycles", "cnn");
}

// The full Cycles render, as our generator writes it: the variance file beside it.
TEST(Presets, CyclesWithVarianceFileRunsTheMixedChain)
{
    const std::string dir = mcdn_test::temp_dir("presets_cycles");
    auto run = run_mcdntool("-v -i " + test_data(kBox + ".exr") + " -i:as=variance "
                            + test_data(kBox + "_var.exr") + " --denoise -o " + dir + "/out.exr");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("AOV preset 'cycles'"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("--denoise runs cnn -> sure -> mix (net):"), std::string::npos)
        << run.output;
    // -v says what becomes of the light passes: denoised here, kept with extras=0.
    EXPECT_NE(run.output.find("denoised with the beauty: DiffDir"), std::string::npos)
        << run.output;
    run =
        run_mcdntool("-v -i " + test_data(kBox + ".exr") + " -i:as=variance "
                     + test_data(kBox + "_var.exr") + " --denoise:extras=0 -o " + dir + "/out.exr");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_EQ(run.output.find("denoised with the beauty"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("kept as rendered: DiffDir"), std::string::npos) << run.output;
}

// A Tungsten buffer directory is detected from the folder layout.
TEST(Presets, TungstenDirectoryIsDetected)
{
    const std::string dir = mcdn_test::temp_dir("presets_tungsten");
    auto run =
        run_mcdntool("-v -i " + test_data("cornell20") + " --denoise -o " + dir + "/out.exr");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("AOV preset 'tungsten'"), std::string::npos) << run.output;
    // A Tungsten folder has half buffers: NFOR is weighed beside the CNN.
    EXPECT_NE(run.output.find("--denoise runs cnn -> sure -> choose (nfor) -> mix (net):"),
              std::string::npos)
        << run.output;
}

TEST(Presets, DetectionSaysWhy)
{
    OIIO::ImageSpec spec(4, 4, 3, OIIO::TypeDesc::FLOAT);
    spec.channelnames = { "Ci.r", "Ci.g", "Ci.b" };
    std::string why;
    EXPECT_EQ(mcdn::detect_aov_preset(spec, &why), "renderman");
    EXPECT_FALSE(why.empty());
    spec.channelnames = { "R", "G", "B" };
    EXPECT_EQ(mcdn::detect_aov_preset(spec, &why), "generic");
    spec.channelnames = { "RGBA.R", "RGBA.G", "RGBA.B" };
    EXPECT_EQ(mcdn::detect_aov_preset(spec, &why), "arnold");
}

}  // namespace

namespace {

/// Writes `parts` (name, image) as one multi-part EXR.
bool write_parts(const std::string& path,
                 const std::vector<std::pair<std::string, ImageBuf>>& parts)
{
    std::vector<OIIO::ImageSpec> specs;
    for (const auto& [name, image] : parts) {
        specs.push_back(image.spec());
        specs.back().attribute("name", name);
    }
    auto out = OIIO::ImageOutput::create(path);
    bool ok = out && out->open(path, int(specs.size()), specs.data());
    for (size_t p = 0; ok && p < parts.size(); ++p)
        ok = (p == 0 || out->open(path, specs[p], OIIO::ImageOutput::AppendSubimage))
             && out->write_image(OIIO::TypeDesc::FLOAT, parts[p].second.localpixels());
    return out && out->close() && ok;
}

}  // namespace

// Arnold's multi-part output: the beauty in the first part, each AOV a part of its own. Read
// as one AOV set (no --aov overrides), written back with the same parts.
TEST(Presets, MultiPartExrIsOneAovSetAndIsWrittenBackInParts)
{
    const std::string dir = mcdn_test::temp_dir("presets_multipart");
    const std::vector<std::pair<std::string, ImageBuf>> parts = {
        { "rgba", assemble(rgb(kRGB, "", "Combined")) },
        { "variance", assemble(rgb(kRGB, "_var", "Combined")) },
        { "N", assemble(rgb({ "X", "Y", "Z" }, "", "Denoising Normal", "XYZ")) },
        { "denoise_albedo", assemble(rgb(kRGB, "", "Denoising Albedo")) },
    };
    ASSERT_TRUE(write_parts(dir + "/beauty.exr", parts));
    auto run = run_mcdntool("-v -i " + dir + "/beauty.exr --denoise -o " + dir + "/out.exr");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("AOV preset 'arnold'"), std::string::npos) << run.output;
    EXPECT_NE(run.output.find("--denoise runs cnn -> sure -> mix (net):"), std::string::npos)
        << run.output;
    auto in = OIIO::ImageInput::open(dir + "/out.exr");
    ASSERT_TRUE(in);
    for (size_t p = 0; p < parts.size(); ++p) {
        ASSERT_TRUE(in->seek_subimage(int(p), 0)) << "part " << p;
        EXPECT_EQ(in->spec().get_string_attribute("name"), parts[p].first);
        EXPECT_EQ(in->spec().channelnames, parts[p].second.spec().channelnames) << parts[p].first;
    }
    EXPECT_FALSE(in->seek_subimage(int(parts.size()), 0)) << "no part added";
    in->close();
    // The beauty part alone, denoised, against the render.
    ImageBuf beauty(dir + "/out.exr", 0, 0);
    ASSERT_TRUE(beauty.read(0, 0, true, OIIO::TypeDesc::FLOAT));
    EXPECT_LT(relmse(beauty, kRGB), 0.5 * relmse(parts[0].second, kRGB));

    // -i:part=NAME reads one part alone.
    run = run_mcdntool("-i:part=rgba " + dir + "/beauty.exr --info");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("3 channels"), std::string::npos) << run.output;
    run = run_mcdntool("-i:part=nonesuch " + dir + "/beauty.exr --info");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(
        run.output.find("no part named 'nonesuch' (parts: rgba, variance, N, denoise_albedo)"),
        std::string::npos)
        << run.output;
}

// A stereo file as OpenEXR writes one (multi-part, each view its own part and data window,
// half/DWAA): each view denoised, each part written back with its window, view, types and
// compression; nothing else is left in the folder (issue 46, item 6; before: "part 1 has
// data window 48x56 at (8,4), part 0 has 64x64 at (0,0)").
TEST(Presets, StereoViewsOfOtherDataWindowsAreEachDenoised)
{
    const std::string dir = mcdn_test::temp_dir("presets_stereo");
    const ImageBuf whole =
        assemble(concat({ rgb(kRGB, "", "Combined"),
                          rgb({ "albedo.R", "albedo.G", "albedo.B" }, "", "Denoising Albedo"),
                          rgb({ "N.X", "N.Y", "N.Z" }, "", "Denoising Normal", "XYZ") }));
    const OIIO::ROI windows[2] = { OIIO::ROI(0, 64, 0, 64), OIIO::ROI(8, 56, 4, 60) };
    const char* views[2] = { "left", "right" };
    std::vector<OIIO::ImageSpec> specs;
    std::vector<ImageBuf> parts;
    for (int v = 0; v < 2; ++v) {
        parts.push_back(OIIO::ImageBufAlgo::cut(whole, windows[v]));
        ImageBuf& part = parts.back();
        part.set_origin(windows[v].xbegin, windows[v].ybegin);
        OIIO::ImageSpec spec = part.spec();
        spec.full_x = spec.full_y = 0;
        spec.full_width = spec.full_height = 64;
        spec.set_format(OIIO::TypeDesc::HALF);
        spec.attribute("name", views[v]);
        spec.attribute("view", views[v]);
        spec.attribute("compression", "dwaa:45");
        specs.push_back(spec);
    }
    const std::string file = dir + "/stereo.exr";
    auto out = OIIO::ImageOutput::create(file);
    ASSERT_TRUE(out && out->open(file, 2, specs.data()));
    for (int v = 0; v < 2; ++v)
        ASSERT_TRUE((v == 0 || out->open(file, specs[size_t(v)], OIIO::ImageOutput::AppendSubimage))
                    && out->write_image(OIIO::TypeDesc::FLOAT, parts[size_t(v)].localpixels()))
            << out->geterror();
    ASSERT_TRUE(out->close());

    auto run = run_mcdntool("-v -i " + file + " --denoise -o " + dir + "/out.exr");
    ASSERT_EQ(run.exit_code, 0) << run.output;
    EXPECT_NE(run.output.find("views left, right"), std::string::npos) << run.output;
    auto in = OIIO::ImageInput::open(dir + "/out.exr");
    ASSERT_TRUE(in);
    for (int v = 0; v < 2; ++v) {
        ASSERT_TRUE(in->seek_subimage(v, 0));
        const OIIO::ImageSpec& spec = in->spec();
        EXPECT_EQ(spec.get_string_attribute("name"), views[v]);
        EXPECT_EQ(spec.get_string_attribute("view"), views[v]);
        EXPECT_EQ(OIIO::ROI(spec.x, spec.x + spec.width, spec.y, spec.y + spec.height), windows[v]);
        EXPECT_EQ(spec.format, OIIO::TypeDesc::HALF);
        EXPECT_EQ(spec.get_string_attribute("compression"), "dwaa");
        ImageBuf denoised(dir + "/out.exr", v, 0), render(file, v, 0);
        ASSERT_TRUE(denoised.read(v, 0, true, OIIO::TypeDesc::FLOAT)) << denoised.geterror();
        ASSERT_TRUE(render.read(v, 0, true, OIIO::TypeDesc::FLOAT)) << render.geterror();
        // Against the reference's pixels of this window.
        ImageBuf reference = OIIO::ImageBufAlgo::cut(read("box16/box_ref.exr"), windows[v]);
        reference.set_origin(windows[v].xbegin, windows[v].ybegin);
        const auto error = [&](const ImageBuf& image) {
            mcdn::MetricsOptions o;
            o.image_channels = { 0, 1, 2 };
            o.reference_channels.clear();
            for (const char* c : { "R", "G", "B" })
                o.reference_channels.push_back(
                    reference.spec().channelindex(std::string("ViewLayer.Combined.") + c));
            mcdn::Metrics m;
            std::string why;
            EXPECT_TRUE(mcdn::compute_metrics(m, image, reference, o, why)) << why;
            return m.relmse;
        };
        EXPECT_LT(error(denoised), 0.5 * error(render)) << views[v];
    }
    EXPECT_FALSE(in->seek_subimage(2, 0)) << "no part added";
    in->close();
    std::vector<std::string> files;
    OIIO::Filesystem::get_directory_entries(dir, files);
    EXPECT_EQ(files.size(), 2u) << "only the input and the output";

    // One output file takes both views: a PNG cannot.
    run = run_mcdntool("-i " + file + " --denoise -o " + dir + "/out.png");
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_NE(run.output.find("give one -o FILE.exr"), std::string::npos) << run.output;
}
