// KPCN (lib/src/cnn, issue 6 item 4): the network's cost (GFLOP per 1920x1080 frame, both
// branches), the time of the whole op's network part on a frame, and the relMSE of the
// render, our NFOR and the CNN on the shared evaluation data (box 16/64, cycles preset) and
// the generated crops training/cnn holds out (datasets/eval if rendered, else the `full`
// crops whose number % 6 == 4) at 16 and 64 spp. The speed part times the network part on
// random inputs and then the whole op (reading the AOVs, inputs, networks, recombination)
// on the box 16 spp render tiled to the frame size, skipping off (needs ../shared/data).
//
//   bench_cnn [--no-quality] [--no-speed] [--size WxH] [--tile N] [weights.mcdnw]
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#include "cnn/cnn_steps.h"
#include "mcdn/cnn.h"
#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn/nfor.h"

#include "bench_data.h"
#include "net_flops.h"
#include "plain_conv.h"

using namespace mcdn;
using mcdn_bench::flops_per_pixel;
using Clock = std::chrono::steady_clock;
namespace fs = std::filesystem;

namespace {

double seconds_since(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// Random raw planes of a frame: smooth-ish radiance with noise, features in range.
kpcn::RawPlanes random_frame(int w, int h)
{
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    kpcn::RawPlanes raw;
    raw.split = true;
    raw.rect = { 0, 0, w, h };
    raw.frame_width = w;
    raw.frame_height = h;
    auto fill = [&](Plane& p, float scale) {
        p = Plane(w, h);
        for (float& v : p.px)
            v = scale * u(rng);
    };
    for (int c = 0; c < 3; ++c) {
        fill(raw.color[c], 1);
        fill(raw.color_var[c], 0.01f);
        fill(raw.diffuse[c], 0.6f);
        fill(raw.diffuse_var[c], 0.01f);
        fill(raw.specular[c], 0.4f);
        fill(raw.specular_var[c], 0.01f);
        fill(raw.demod[c], 1);
        fill(raw.albedo[c], 1);
        fill(raw.albedo_var[c], 0.001f);
        fill(raw.normal[c], 1);
        fill(raw.normal_var[c], 0.001f);
    }
    fill(raw.depth, 1);
    fill(raw.depth_var, 0.001f);
    return raw;
}

void speed(kpcn::Model& model, int w, int h, int tile)
{
    kpcn::RawPlanes raw = random_frame(w, h);
    nn::TileOptions tiles;
    tiles.tile_size = tile;
    const double gflop =
        (flops_per_pixel(model.diffuse) + flops_per_pixel(model.specular)) * double(w) * h / 1e9;
    std::string error;
    const mcdn_bench::Timing t = mcdn_bench::timed([&] {
        for (auto [net, branch] : { std::pair { &model.diffuse, kpcn::Branch::diffuse },
                                    std::pair { &model.specular, kpcn::Branch::specular } }) {
            // Inputs per tile, as the op makes them (without reading the AOVs).
            auto make_inputs = [&, branch = branch](const Rect& window, std::vector<nn::Tensor>& in,
                                                    std::string&) {
                in.resize(2);
                kpcn::branch_inputs(raw, branch, window, in[0], in[1]);
                return true;
            };
            std::vector<nn::Tensor> out;
            if (!nn::run_tiled(*net, h, w, make_inputs, out, error, tiles))
                std::fprintf(stderr, "%s\n", error.c_str());
            model.diffuse.give_buffers(model.specular);  // as the op does
        }
    });
    std::printf("%dx%d, tile %d (halo %d): %.2f s wall, %.2f CPU-s for both branches, %.1f GFLOP "
                "(nominal): %.1f GFLOP/s, %.1f GFLOP per CPU-s\n",
                w, h, tile, model.diffuse.receptive_radius(), t.wall, t.cpu, gflop, gflop / t.wall,
                gflop / t.cpu);
}

std::string shared(const std::string& rel)
{
    return std::string(MCDN_SHARED_DATA) + "/" + rel;
}

/// The box 16 spp render (mean and variance: every pass KPCN reads, with the split) tiled
/// to w x h; an empty buffer without ../shared/data.
ImageBuf tiled_box(int w, int h)
{
    const std::string stem = shared("box/box_0016spp");
    ImageBuf box, frame;
    if (!fs::exists(stem + ".exr")
        || !read_inputs(box, { { stem + ".exr", InputKind::Mean },
                               { stem + "_var.exr", InputKind::Variance } }))
        return frame;
    ImageSpec spec = box.spec();
    const int bw = spec.width, bh = spec.height, channels = spec.nchannels;
    std::vector<float> tile(size_t(bw) * bh * channels), px(size_t(w) * h * channels);
    box.get_pixels(box.roi(), OIIO::TypeDesc::FLOAT, tile.data());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            std::copy_n(&tile[(size_t(y % bh) * bw + x % bw) * channels], channels,
                        &px[(size_t(y) * w + x) * channels]);
    spec.width = spec.full_width = w;
    spec.height = spec.full_height = h;
    frame.reset(spec);
    frame.set_pixels(frame.roi(), OIIO::TypeDesc::FLOAT, px.data());
    return frame;
}

/// The whole op on the tiled box frame, skipping off (every tile runs the networks).
void op_speed(const std::string& weights, int w, int h, int tile)
{
    const ImageBuf frame = tiled_box(w, h);
    if (!frame.initialized()) {
        std::printf("whole op: skipped (needs ../shared/data/box)\n");
        return;
    }
    CnnOptions options;
    options.weights = weights;
    options.tile_size = tile;
    options.skip.enabled = false;
    ImageBuf out;
    const mcdn_bench::Timing t = mcdn_bench::timed([&] { cnn(out, frame, options); });
    if (out.has_error())
        std::fprintf(stderr, "%s\n", out.geterror().c_str());
    std::printf("whole op on the box frame %dx%d (%d channels), tile %d: %.2f s wall, %.2f CPU-s\n",
                w, h, frame.nchannels(), tile, t.wall, t.cpu);
}

/// The yardstick timed in the same run: one plain oneDNN 3x3 48->48 conv of the frame's size.
void plain_conv(int w, int h, double frame_gflop)
{
    double flops = 0;
    const mcdn_bench::Timing t = mcdn_bench::plain_onednn_conv(h, w, 48, 48, 3, 2, &flops);
    std::printf("yardstick: one plain oneDNN 3x3 48->48 conv + ReLU on %dx%d: %.2f s wall, %.2f "
                "CPU-s, %.1f GFLOP: %.1f GFLOP per CPU-s (the frame is %.1f such convs in FLOPs)\n",
                w, h, t.wall, t.cpu, flops / 1e9, flops / 1e9 / t.cpu, frame_gflop * 1e9 / flops);
}

struct Input {
    std::string name;
    int spp;
    std::string stem, reference;
};

std::vector<Input> inputs()
{
    std::vector<Input> list;
    for (int spp : { 16, 64 }) {
        char stem[64];
        std::snprintf(stem, sizeof stem, "box/box_%04dspp", spp);
        if (fs::exists(shared(stem) + ".exr"))
            list.push_back({ "box", spp, shared(stem), shared("box/box_ref.exr") });
    }
    bool eval = false;
    const fs::path root = mcdn_bench::generated_dataset(eval);
    if (!fs::exists(root))
        return list;
    std::vector<fs::path> crops;
    for (const auto& entry : fs::directory_iterator(root))
        if (entry.is_directory() && fs::exists(entry.path() / "crop.json"))
            crops.push_back(entry.path());
    std::sort(crops.begin(), crops.end());
    for (const fs::path& dir : crops) {
        const std::string crop = dir.filename().string();
        if (!eval && std::atoi(crop.substr(0, 4).c_str()) % 6 != 4)
            continue;  // a training crop
        for (int spp : { 16, 64 }) {
            char level[32];
            std::snprintf(level, sizeof level, "_%04dspp", spp);
            const std::string stem = (dir / (crop + level)).string();
            if (fs::exists(stem + "_B.exr"))
                list.push_back({ (eval ? "eval/" : "full/") + crop, spp, stem,
                                 (dir / (crop + "_ref.exr")).string() });
        }
    }
    return list;
}

double relmse(const ImageBuf& image, const ImageBuf& ref, bool trim = false)
{
    auto color = [](const ImageBuf& b) {
        const int r = b.spec().channelindex("ViewLayer.Combined.R");
        return std::vector<int> { r, r + 1, r + 2 };
    };
    MetricsOptions mo;
    mo.image_channels = color(image);
    mo.reference_channels = color(ref);
    mo.trim = trim;  // KPCN §6: 0.01% best and worst pixels dropped
    Metrics m;
    std::string error;
    if (!compute_metrics(m, image, ref, mo, error)) {
        std::fprintf(stderr, "metrics: %s\n", error.c_str());
        return NAN;
    }
    return m.relmse;
}

void quality(const std::string& weights)
{
    std::printf(
        "\nrelMSE, and in brackets trimmed as KPCN reports it (0.01%% best/worst dropped)\n");
    std::printf("%-22s %5s %20s %20s %20s %7s %7s\n", "input", "spp", "noisy", "NFOR", "CNN",
                "NFOR s", "CNN s");
    double log_sum[6] = {}, count = 0;
    for (const Input& in : inputs()) {
        ImageBuf src, ref;
        if (!read_inputs(src, { { in.stem + ".exr", InputKind::Mean },
                                { in.stem + "_var.exr", InputKind::Variance },
                                { in.stem + "_A.exr", InputKind::HalfA },
                                { in.stem + "_B.exr", InputKind::HalfB } })
            || !read_image(ref, in.reference)) {
            std::fprintf(stderr, "%s: %s %s\n", in.stem.c_str(), src.geterror().c_str(),
                         ref.geterror().c_str());
            continue;
        }
        CnnOptions co;
        co.weights = weights;
        auto t0 = Clock::now();
        ImageBuf nf = nfor(src);
        const double nfor_s = seconds_since(t0);
        t0 = Clock::now();
        ImageBuf cn = cnn(src, co);
        const double cnn_s = seconds_since(t0);
        if (cn.has_error() || nf.has_error()) {
            std::fprintf(stderr, "%s: %s %s\n", in.name.c_str(), cn.geterror().c_str(),
                         nf.geterror().c_str());
            continue;
        }
        const double e[6] = {
            relmse(src, ref),      relmse(src, ref, true), relmse(nf, ref),
            relmse(nf, ref, true), relmse(cn, ref),        relmse(cn, ref, true)
        };
        std::printf("%-22s %5d %9.5f (%8.5f) %9.5f (%8.5f) %9.5f (%8.5f) %7.2f %7.2f\n",
                    in.name.c_str(), in.spp, e[0], e[1], e[2], e[3], e[4], e[5], nfor_s, cnn_s);
        for (int k = 0; k < 6; ++k)
            log_sum[k] += std::log(e[k]);
        ++count;
    }
    if (count > 0) {
        double g[6];
        for (int k = 0; k < 6; ++k)
            g[k] = std::exp(log_sum[k] / count);
        std::printf("%-22s %5s %9.5f (%8.5f) %9.5f (%8.5f) %9.5f (%8.5f)\n", "geometric mean", "",
                    g[0], g[1], g[2], g[3], g[4], g[5]);
    }
}

}  // namespace

int main(int argc, char** argv)
{
    bool do_quality = true, do_speed = true;
    int w = 1920, h = 1080;
    std::vector<int> tiles = { 256, 512 };
    std::string weights = default_cnn_weights();
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--no-quality"))
            do_quality = false;
        else if (!std::strcmp(argv[i], "--no-speed"))
            do_speed = false;
        else if (!std::strcmp(argv[i], "--tile") && i + 1 < argc)
            tiles = { std::atoi(argv[++i]) };
        else if (!std::strcmp(argv[i], "--size") && i + 1 < argc)
            std::sscanf(argv[++i], "%dx%d", &w, &h);
        else
            weights = argv[i];
    }
    kpcn::Model model;
    std::string error;
    if (!kpcn::load_model(model, weights, error)) {
        std::fprintf(stderr, "%s\n", error.c_str());
        return 1;
    }
    const double per_pixel = flops_per_pixel(model.diffuse) + flops_per_pixel(model.specular);
    std::printf("model %s\n%.1f kFLOP per pixel (both branches): %.1f GFLOP per 1920x1080 frame; "
                "receptive radius %d px\n",
                weights.c_str(), per_pixel / 1e3, per_pixel * 1920 * 1080 / 1e9,
                model.diffuse.receptive_radius());
    if (do_speed) {
        plain_conv(w, h, per_pixel * w * h / 1e9);
        for (int tile : tiles)
            speed(model, w, h, tile);
        for (int tile : tiles)
            op_speed(weights, w, h, tile);
    }
    if (do_quality)
        quality(weights);
    return 0;
}
