// Progressive mix (PD §4, Table 4): errors of the render, our NFOR and five mixes — the
// network (§4.3) and the analytic eq. 9, each with and without the t-test (eq. 18), and the
// network + t-test without its outlier floor (lib/src/mix/outlier_floor.cpp) — on the
// shared evaluation data and the held-out generated crops; the properties of issue 5 item 4
// checked on them; and the speed of a 1920x1080 mix pass (without the denoiser runs) as a
// ratio to one plain oneDNN 3x3 48->48 convolution of the same size, timed in the same run.
//
//   bench_mix [--no-speed | --only-speed] [--no-generated] [--crop DIR]... [--blur WIDTH]
//             [--cnn] [--floor V] [--drop V] [--cache DIR] [weights.mcdnw]
//
// --blur WIDTH replaces NFOR with a deliberately biased "denoiser": a Gaussian blur of the
// colour, WIDTH pixels wide (OIIO's make_kernel). It is how the properties that need a
// denoiser worse than the render at high spp are measured (PD §4: the mix is consistent for
// any denoiser; α' must fall toward the render as spp grows). Our NFOR never is worse on
// the data we have.
//
// --floor V and --drop V set MixOptions::outlier_relative_variance and drop_relative_variance
// of the mixes with a floor (default: the options' defaults). --cache DIR keeps each input's
// render + denoised + SURE frame (the two denoiser runs, most of the time) in DIR and reads it
// back on later runs with the same denoiser: for comparing mix settings. Delete DIR when the
// denoiser changes.
//
// --cnn denoises with mcdn::cnn (models/kpcn.mcdnw) instead of NFOR, and mixes with the
// network trained for it (models/mix_cnn.mcdnw unless a weights file is given; issue 5:
// "with --cnn once it exists").
//
// --crop DIR adds every level of one generated crop (DIR/<name>_00NNspp*.exr, DIR/<name>_ref.exr),
// e.g. a training crop where a mix went wrong (datasets/small/0001_exterior).
//
// Generated crops: $MCDN_CACHE (~/.cache/mcdenoise)/datasets/eval/* if rendered, else the
// crops of datasets/full that training/mix holds out (crop number % 6 == 4).
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include <oneapi/dnnl/dnnl.hpp>

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/cnn.h"
#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/sure.h"
#include "mix/mix_steps.h"

#include "bench_data.h"
#include "plain_conv.h"

using namespace mcdn;
namespace fs = std::filesystem;

namespace {

struct Input {
    std::string scene;  // a scene's levels are compared with each other (convergence)
    int spp;
    std::vector<InputFile> files;
    std::string preset, reference;
};

std::string shared(const std::string& rel)
{
    return std::string(MCDN_SHARED_DATA) + "/" + rel;
}

std::vector<InputFile> level_files(const std::string& stem)
{
    return { { stem + ".exr", InputKind::Mean },
             { stem + "_var.exr", InputKind::Variance },
             { stem + "_A.exr", InputKind::HalfA },
             { stem + "_B.exr", InputKind::HalfB } };
}

void add_crop_levels(std::vector<Input>& list, const fs::path& dir, const std::string& label)
{
    const std::string crop = dir.filename().string();
    const std::string ref = (dir / (crop + "_ref.exr")).string();
    if (!fs::exists(ref))
        return;
    for (int spp : { 4, 16, 64, 256, 1024 }) {
        char level[32];
        std::snprintf(level, sizeof level, "_%04dspp", spp);
        const std::string stem = (dir / (crop + level)).string();
        if (fs::exists(stem + "_B.exr"))
            list.push_back({ label, spp, level_files(stem), "cycles", ref });
    }
}

std::vector<Input> inputs(bool generated, const std::vector<std::string>& extra_crops)
{
    std::vector<Input> list;
    for (int spp : { 16, 64, 256 }) {
        char stem[64];
        std::snprintf(stem, sizeof stem, "box/box_%04dspp", spp);
        list.push_back(
            { "box", spp, level_files(shared(stem)), "cycles", shared("box/box_ref.exr") });
    }
    for (const char* scene : { "cornell20", "materialtest" })
        list.push_back({ scene,
                         16,
                         { { shared(std::string("tungsten/") + scene), InputKind::Mean } },
                         "tungsten",
                         shared(std::string("tungsten/") + scene + "/ref.pfm") });
    for (const std::string& dir : extra_crops) {
        const fs::path path = fs::path(dir).lexically_normal();
        add_crop_levels(list, path,
                        path.parent_path().filename().string() + "/" + path.filename().string());
    }
    if (!generated)
        return list;
    bool eval = false;
    const fs::path root = mcdn_bench::generated_dataset(eval);
    if (!fs::exists(root))
        return list;
    std::vector<fs::path> crops;
    for (const auto& entry : fs::directory_iterator(root))
        if (entry.is_directory())
            crops.push_back(entry.path());
    std::sort(crops.begin(), crops.end());
    for (const fs::path& dir : crops) {
        const std::string crop = dir.filename().string();
        if (!eval && (crop.size() < 4 || std::atoi(crop.substr(0, 4).c_str()) % 6 != 4))
            continue;  // a training crop
        add_crop_levels(list, dir, (eval ? "eval/" : "full/") + crop);
    }
    return list;
}

std::vector<int> color_channels(const ImageBuf& b)
{
    const ImageSpec& s = b.spec();
    std::vector<int> c;
    for (const char* n : { "ViewLayer.Combined.R", "ViewLayer.Combined.G", "ViewLayer.Combined.B" })
        if (s.channelindex(n) >= 0)
            c.push_back(s.channelindex(n));
    if (c.size() == 3)
        return c;
    return { s.channelindex("R"), s.channelindex("G"), s.channelindex("B") };
}

bool metrics_of(Metrics& m, const ImageBuf& image, const ImageBuf& ref)
{
    MetricsOptions mo;
    mo.image_channels = color_channels(image);
    mo.reference_channels = color_channels(ref);
    std::string error;
    if (!compute_metrics(m, image, ref, mo, error)) {
        std::fprintf(stderr, "metrics: %s\n", error.c_str());
        return false;
    }
    return true;
}

double mean_of_channels(const ImageBuf& b, const char* const names[3])
{
    double sum = 0;
    size_t n = 0;
    for (int c = 0; c < 3; ++c) {
        const int ch = b.spec().channelindex(names[c]);
        for (OIIO::ImageBuf::ConstIterator<float> it(b); !it.done(); ++it, ++n)
            sum += it[ch];
    }
    return n ? sum / n : 0;
}

/// A 1920x1080 buffer with everything mix reads (generic channel names), noise-like values.
ImageBuf synthetic_frame(int width, int height)
{
    std::vector<std::string> names = { "R", "G", "B", "variance.R", "variance.G", "variance.B" };
    for (const auto* group : { sure_channels::kNoisy, sure_channels::kSure,
                               sure_channels::kDivergence, sure_channels::kResidual })
        for (int c = 0; c < 3; ++c)
            names.push_back(group[c]);
    ImageSpec spec(width, height, int(names.size()), OIIO::TypeFloat);
    spec.channelnames = names;
    ImageBuf buf(spec);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (OIIO::ImageBuf::Iterator<float> it(buf); !it.done(); ++it)
        for (int c = 0; c < spec.nchannels; ++c)
            it[c] = c < 3 ? 0.5f + 0.1f * u(rng) : 0.01f * u(rng);
    return buf;
}

/// Mean alpha' over the pixel-channels where the denoised image y is off the reference by
/// more than 3 standard deviations of the render there (|y - r| > 3 sqrt(Var[x])): where the
/// denoiser is biased at this sample count, so the mix should lean to the render (PD §4:
/// alpha' -> 0 there as spp grows). share: the fraction of pixel-channels that qualify.
double alpha_where_biased(const ImageBuf& z, const ImageBuf& with_sure, const ImageBuf& ref,
                          const AovSpec& aovs, double& share)
{
    AovSet set;
    std::string error;
    share = 0;
    if (!resolve_aovs(set, aovs, with_sure.spec(), error))
        return 0;
    const std::vector<int> y = color_channels(with_sure), r = color_channels(ref);
    const std::vector<int>& var = set.channels(Role::ColorVariance);
    const char* alpha_names[3] = { "mix.alpha.R", "mix.alpha.G", "mix.alpha.B" };
    double sum = 0;
    size_t n = 0, total = 0;
    for (int py = 0; py < z.spec().height; ++py)
        for (int px = 0; px < z.spec().width; ++px)
            for (int c = 0; c < 3; ++c, ++total) {
                const float off =
                    with_sure.getchannel(px, py, 0, y[c]) - ref.getchannel(px, py, 0, r[c]);
                const float sigma =
                    std::sqrt(std::max(0.0f, with_sure.getchannel(px, py, 0, var[c])));
                if (std::fabs(off) > 3 * sigma) {
                    sum += z.getchannel(px, py, 0, z.spec().channelindex(alpha_names[c]));
                    ++n;
                }
            }
    share = total ? double(n) / total : 0;
    return n ? sum / n : 0;
}

/// The biased stand-in denoiser of --blur: the colour convolved with a WIDTH-wide Gaussian
/// (edges clamp), every other channel passed through.
bool blur_color(ImageBuf& dst, const ImageBuf& src, float width)
{
    const std::vector<int> rgb = color_channels(src);
    const ImageBuf kernel = OIIO::ImageBufAlgo::make_kernel("gaussian", width, width);
    dst = src.copy(OIIO::TypeDesc::FLOAT);
    for (int c : rgb) {  // into the copy, one channel at a time: the others stay as they are
        ROI one = src.roi();
        one.chbegin = c;
        one.chend = c + 1;
        if (!OIIO::ImageBufAlgo::convolve(dst, src, kernel, true, one))
            return dst.errorfmt("blur: {}", dst.geterror()), false;
    }
    return true;
}

constexpr int kMixes = 5;
const char* kMixNames[kMixes] = { "net+t", "net", "analytic+t", "analytic", "net+t nofloor" };
struct Row {
    Input in;
    Metrics render, nfor, mix[kMixes];
    double alpha[kMixes];
    double biased_alpha[kMixes], biased_share;
};

}  // namespace

int main(int argc, char** argv)
{
    bool speed = true, generated = true, accuracy = true;
    std::string weights;
    std::vector<std::string> extra_crops;
    float blur_width = 0;  // 0: NFOR (or the CNN with --cnn)
    bool use_cnn = false;
    float floor = MixOptions().outlier_relative_variance;
    float drop = -1;  // -1: the option's default
    bool no_analytic_floor = false;
    std::string cache;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--crop" && i + 1 < argc)
            extra_crops.push_back(argv[++i]);
        else if (a == "--no-speed")
            speed = false;
        else if (a == "--only-speed")
            accuracy = false;
        else if (a == "--blur" && i + 1 < argc)
            blur_width = std::strtof(argv[++i], nullptr);
        else if (a == "--cnn")
            use_cnn = true;
        else if (a == "--floor" && i + 1 < argc)
            floor = std::strtof(argv[++i], nullptr);
        else if (a == "--no-analytic-floor")
            no_analytic_floor = true;
        else if (a == "--drop" && i + 1 < argc)
            drop = std::strtof(argv[++i], nullptr);
        else if (a == "--cache" && i + 1 < argc)
            cache = argv[++i];
        else if (a == "--no-generated")
            generated = false;
        else
            weights = a;
    }
    if (weights.empty())  // the network of the denoiser (the blur: NFOR's, as for any other)
        weights = default_mix_weights(use_cnn && blur_width <= 0 ? "cnn" : "nfor");
    const std::string den = blur_width > 0 ? "blur" + std::to_string(int(blur_width))
                            : use_cnn      ? "CNN"
                                           : "NFOR";
    std::printf("mcdenoise progressive mix benchmark (PD §4, Table 4); network %s; denoiser %s\n\n",
                weights.c_str(), den.c_str());

    std::vector<Row> rows;
    for (const Input& in : accuracy ? inputs(generated, extra_crops) : std::vector<Input>()) {
        ImageBuf src, ref;
        if (!read_inputs(src, in.files) || !read_image(ref, in.reference)) {
            std::fprintf(stderr, "%s %d spp: %s%s (skipped)\n", in.scene.c_str(), in.spp,
                         src.geterror().c_str(), ref.geterror().c_str());
            continue;
        }
        AovSpec aovs;
        aovs.preset = in.preset;
        NforOptions no;
        no.aovs = aovs;
        CnnOptions co;
        co.aovs = aovs;
        SureOptions so;
        so.aovs = aovs;
        Denoiser denoiser = [&](ImageBuf& dst, const ImageBuf& s) {
            return blur_width > 0 ? blur_color(dst, s, blur_width)
                   : use_cnn      ? cnn(dst, s, co)
                                  : nfor(dst, s, no);
        };
        ImageBuf with_sure;
        std::string cached;
        if (!cache.empty()) {
            std::string name = in.scene + "_" + std::to_string(in.spp) + "_" + den + ".exr";
            std::replace(name.begin(), name.end(), '/', '_');
            cached = (fs::path(cache) / name).string();
            fs::create_directories(cache);
        }
        if (!cached.empty() && fs::exists(cached) && read_image(with_sure, cached)) {
            // the denoiser runs of an earlier bench_mix --cache
        } else if (!sure(with_sure, src, denoiser, so)) {
            std::fprintf(stderr, "%s: %s\n", in.scene.c_str(), with_sure.geterror().c_str());
            continue;
        }
        if (!cached.empty() && !fs::exists(cached)) {
            WriteOptions every_channel;
            every_channel.channels = with_sure.spec().channelnames;
            std::string error;
            if (!write_image(with_sure, cached, every_channel, error))
                std::fprintf(stderr, "%s\n", error.c_str());
        }
        Row row { in, {}, {}, {}, {}, {}, 0 };
        bool ok = metrics_of(row.render, src, ref) && metrics_of(row.nfor, with_sure, ref);
        for (int m = 0; m < kMixes && ok; ++m) {
            MixOptions mo;
            mo.aovs = aovs;
            mo.model = m < 2 || m == 4 ? MixOptions::Model::Net : MixOptions::Model::Analytic;
            mo.weights = weights;
            mo.t_test = m % 2 == 0;
            mo.outlier_relative_variance = m == 4 ? 0 : floor;
            if (drop >= 0 || m == 4)
                mo.drop_relative_variance = m == 4 ? 0 : drop;
            if (no_analytic_floor || m == 4)
                mo.analytic_floor = false;
            mo.output_alpha = true;
            ImageBuf z;
            if (!mix(z, with_sure, mo)) {
                std::fprintf(stderr, "%s: %s\n", in.scene.c_str(), z.geterror().c_str());
                return 1;
            }
            const char* alpha_names[3] = { "mix.alpha.R", "mix.alpha.G", "mix.alpha.B" };
            row.alpha[m] = mean_of_channels(z, alpha_names);
            row.biased_alpha[m] = alpha_where_biased(z, with_sure, ref, aovs, row.biased_share);
            ok = metrics_of(row.mix[m], z, ref);
        }
        if (!ok)
            continue;
        rows.push_back(row);
        std::fprintf(stderr, "%s %d spp done\n", in.scene.c_str(), in.spp);
    }

    if (accuracy) {
        std::printf(
            "| input | spp | RMSE render | RMSE %s | RMSE net+t | net | analytic+t | analytic "
            "| net+t nofloor | relMSE render | %s | net+t | net | analytic+t | analytic "
            "| net+t nofloor | mean alpha' net+t | analytic+t |\n",
            den.c_str(), den.c_str());
        std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---"
                    ":|---:|---:|\n");
        for (const Row& r : rows) {
            std::printf("| %s | %d | %.4f | %.4f", r.in.scene.c_str(), r.in.spp, r.render.rmse,
                        r.nfor.rmse);
            for (const Metrics& m : r.mix)
                std::printf(" | %.4f", m.rmse);
            std::printf(" | %.5f | %.5f", r.render.relmse, r.nfor.relmse);
            for (const Metrics& m : r.mix)
                std::printf(" | %.5f", m.relmse);
            std::printf(" | %.3f | %.3f |\n", r.alpha[0], r.alpha[2]);
        }

        // Table 4 shape: mean RMSE per sample count over the inputs that have it.
        std::map<int, std::vector<const Row*>> by_spp;
        for (const Row& r : rows)
            by_spp[r.in.spp].push_back(&r);
        std::printf("\nMean RMSE per sample count (PD Table 4 layout)\n\n| model |");
        for (const auto& [spp, list] : by_spp)
            std::printf(" %d spp (n=%zu) |", spp, list.size());
        std::printf("\n|---|");
        for (size_t i = 0; i < by_spp.size(); ++i)
            std::printf("---:|");
        std::printf("\n");
        auto mean_rmse = [](const std::vector<const Row*>& list, int which) {
            double s = 0;
            for (const Row* r : list)
                s += which == -2 ? r->render.rmse : which == -1 ? r->nfor.rmse : r->mix[which].rmse;
            return s / list.size();
        };
        const std::pair<const char*, int> models[] = { { "mc-render", -2 },
                                                       { den.c_str(), -1 },
                                                       { "mix net + t-test", 0 },
                                                       { "mix net, no t-test", 1 },
                                                       { "mix analytic + t-test", 2 },
                                                       { "mix analytic, no t-test", 3 },
                                                       { "mix net + t-test, no outlier floor",
                                                         4 } };
        for (auto [name, which] : models) {
            std::printf("| %s |", name);
            for (const auto& [spp, list] : by_spp)
                std::printf(" %.4f |", mean_rmse(list, which));
            std::printf("\n");
        }

        // Issue 5 item 4, per mix model.
        std::printf("\nProperties (issue 5 item 4), RMSE:\n");
        for (int m = 0; m < kMixes; ++m) {
            int within = 0;
            std::string misses;
            for (const Row& r : rows) {
                const double better = std::min(r.render.rmse, r.nfor.rmse);
                if (r.mix[m].rmse <= better * 1.02)
                    ++within;
                else
                    misses += " " + r.in.scene + "@" + std::to_string(r.in.spp) + "("
                              + std::to_string(int(std::round(100 * (r.mix[m].rmse / better - 1))))
                              + "%)";
            }
            std::printf("  %-13s mix <= min(render, %s) + 2%%: %d of %zu inputs;%s\n", kMixNames[m],
                        den.c_str(), within, rows.size(),
                        misses.empty() ? " all" : (" over:" + misses).c_str());
        }
        // Scenes with several levels: alpha' trend and the averaged-over-spp gain where NFOR is
        // worse than the render at the highest level.
        std::map<std::string, std::vector<const Row*>> by_scene;
        for (const Row& r : rows)
            by_scene[r.in.scene].push_back(&r);
        for (const auto& [scene, list] : by_scene) {
            if (list.size() < 2)
                continue;
            const Row* top = list.back();
            std::printf("  %s: alpha'(net+t) by spp:", scene.c_str());
            for (const Row* r : list)
                std::printf(" %d:%.3f", r->in.spp, r->alpha[0]);
            std::printf("; where %s is biased (|y - r| > 3 sqrt(Var[x]), share of pixel-channels):",
                        den.c_str());
            for (const Row* r : list)
                std::printf(" %d:%.3f (%.1f%%)", r->in.spp, r->biased_alpha[0],
                            100 * r->biased_share);
            double nfor_mean = 0, mix_mean[kMixes] = {};
            for (const Row* r : list) {
                nfor_mean += r->nfor.rmse / list.size();
                for (int m = 0; m < kMixes; ++m)
                    mix_mean[m] += r->mix[m].rmse / list.size();
            }
            if (top->nfor.rmse > top->render.rmse) {
                std::printf("; %s worse than render at %d spp: mean-over-spp RMSE gain vs it",
                            den.c_str(), top->in.spp);
                for (int m = 0; m < kMixes; ++m)
                    std::printf(" %s %.0f%%%s", kMixNames[m], 100 * (1 - mix_mean[m] / nfor_mean),
                                mix_mean[m] <= 0.8 * nfor_mean ? "" : " (<20%)");
            }
            std::printf("\n");
        }
    }

    if (speed) {
        const int width = 1920, height = 1080;
        ImageBuf frame = synthetic_frame(width, height);
        MixOptions mo;
        mo.aovs.preset = "generic";
        mo.model = MixOptions::Model::Net;
        mo.weights = weights;
        mo.analytic_floor = !no_analytic_floor;
        ImageBuf z;
        const mcdn_bench::Timing mix_t = mcdn_bench::fastest_of(2, [&] {
            if (!mix(z, frame, mo))
                std::fprintf(stderr, "%s\n", z.geterror().c_str());
        });
        mo.t_test = false;
        const mcdn_bench::Timing net_t = mcdn_bench::fastest_of(2, [&] { mix(z, frame, mo); });
        double conv_flops = 0;
        const mcdn_bench::Timing conv_t =
            mcdn_bench::plain_onednn_conv(height, width, 48, 48, 3, 3, &conv_flops);
        // The mixing network's FLOPs: 5x5 18->48, four 3x3 48->48, 3x3 48->9.
        const double net_flops =
            2.0 * width * height * (25 * 18 * 48 + 4 * 9 * 48 * 48 + 9 * 48 * 9);
        std::printf(
            "\n1920x1080 mix pass (net + t-test, without denoiser runs): %.3f s wall, %.2f CPU-s "
            "(%.3f s, %.2f CPU-s without the t-test); one plain oneDNN 3x3 48->48 conv + ReLU of "
            "the same size: %.3f s, %.2f CPU-s; ratio %.1fx wall, %.1fx CPU (the network is %.1f "
            "such convs in FLOPs); network %.1f GFLOP: %.1f GFLOP per CPU-s with t-test, conv "
            "%.1f GFLOP per CPU-s\n",
            mix_t.wall, mix_t.cpu, net_t.wall, net_t.cpu, conv_t.wall, conv_t.cpu,
            mix_t.wall / conv_t.wall, mix_t.cpu / conv_t.cpu, net_flops / conv_flops,
            net_flops / 1e9, net_flops / 1e9 / mix_t.cpu, conv_flops / 1e9 / conv_t.cpu);
    }
    return 0;
}
