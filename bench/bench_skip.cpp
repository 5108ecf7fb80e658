// Skipping converged tiles (mcdn/skip.h, issue 8 item 3): a frame whose left half of tiles is
// converged against the same frame all noisy, timed in the same run.
//
//   bench_skip [--spp 16|64|256] [--threads N] [--repeat N] [--only CHAIN] [--tile N]
//              [--converged-spp N]
//
// The all-noisy frame is box at the given spp (../shared/data/box, every channel with its
// variance and halves). The half-converged frame is the same with the left 128 columns (4 of
// 8 tile columns) taken from the 4096-spp reference: every channel's mean and both halves
// are the reference's, its variance the reference's (box_ref_var.exr) scaled to
// --converged-spp (default 65536: 16 times the reference's samples, of the quality the
// default threshold passes, mcdn/skip.h). Each chain runs on
// both frames with skipping on, and on the half-converged frame with skipping off; times are
// the best of --repeat runs, as wall time and as process CPU time (all threads; steadier on a
// busy machine). The ratio the issue asks for is half-converged / all-noisy with skipping on
// (target <= 0.60). Errors: relMSE against the reference over the whole frame and over the
// noisy right half (the left half passed through is the reference itself, error 0, by
// construction; without skipping it is what the denoiser does to a converged render).
// --tile N repeats every image N×N times (a larger frame, same content). Skips (exit 0) when
// ../shared/data is absent.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <functional>
#include <string>
#include <vector>

#include <sys/resource.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>

#include "skip/converged_tiles.h"
#include "mcdn/cnn.h"
#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/sure.h"

using namespace mcdn;
using Clock = std::chrono::steady_clock;

namespace {

std::string data(const std::string& rel)
{
    return std::string(MCDN_SHARED_DATA) + "/" + rel;
}

double cpu_seconds()
{
    rusage u {};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

/// Left `columns` of every channel of the merged render from the reference (mean, halves)
/// and its variance file.
ImageBuf converge_left(const ImageBuf& render, const ImageBuf& ref, const ImageBuf& ref_var,
                       int columns, float variance_scale)
{
    ImageBuf out = render.copy(OIIO::TypeDesc::FLOAT);
    const OIIO::ImageSpec& spec = out.spec();
    for (int rc = 0; rc < ref.spec().nchannels; ++rc) {
        const std::string& name = ref.spec().channelnames[rc];
        const int vc = ref_var.spec().channelindex(name);
        const int targets[4] = { spec.channelindex(name), spec.channelindex("A." + name),
                                 spec.channelindex("B." + name),
                                 spec.channelindex("variance." + name) };
        for (int y = 0; y < spec.height; ++y)
            for (int x = 0; x < columns; ++x) {
                float* px = static_cast<float*>(out.pixeladdr(x, y));
                for (int t = 0; t < 3; ++t)
                    if (targets[t] >= 0)
                        px[targets[t]] = ref.getchannel(x, y, 0, rc);
                if (targets[3] >= 0 && vc >= 0)
                    px[targets[3]] = variance_scale * ref_var.getchannel(x, y, 0, vc);
            }
    }
    return out;
}

/// `image` repeated n×n times.
ImageBuf tiled(const ImageBuf& image, int n)
{
    if (n <= 1)
        return image;
    OIIO::ImageSpec spec = image.spec();
    spec.width *= n;
    spec.height *= n;
    spec.full_width = spec.width;
    spec.full_height = spec.height;
    spec.set_format(OIIO::TypeDesc::FLOAT);
    ImageBuf out(spec);
    for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i)
            OIIO::ImageBufAlgo::paste(out, i * image.spec().width, j * image.spec().height, 0, 0,
                                      image);
    return out;
}

struct Timing {
    double wall = 1e30, cpu = 1e30;
};

Timing best(Timing a, Timing b)
{
    return { std::min(a.wall, b.wall), std::min(a.cpu, b.cpu) };
}

using Chain = std::function<bool(ImageBuf&, const ImageBuf&)>;

Timing time_chain(const Chain& chain, const ImageBuf& src, ImageBuf& result, int repeat)
{
    Timing t;
    for (int r = 0; r < repeat; ++r) {
        const auto w0 = Clock::now();
        const double c0 = cpu_seconds();
        ImageBuf out;
        if (!chain(out, src)) {
            std::fprintf(stderr, "bench_skip: %s\n", out.geterror().c_str());
            std::exit(1);
        }
        t.wall = std::min(t.wall, std::chrono::duration<double>(Clock::now() - w0).count());
        t.cpu = std::min(t.cpu, cpu_seconds() - c0);
        result = std::move(out);
    }
    return t;
}

double relmse(const ImageBuf& image, const std::vector<int>& rgb, const ImageBuf& ref,
              const std::vector<int>& ref_rgb, int x0, int x1)
{
    MetricsOptions mo;
    mo.image_channels = rgb;
    mo.reference_channels = ref_rgb;
    Metrics m;
    std::string error;
    OIIO::ROI roi(x0, x1, 0, image.spec().height);
    if (!compute_metrics(m, image, ref, mo, error, roi)) {
        std::fprintf(stderr, "bench_skip: metrics: %s\n", error.c_str());
        std::exit(1);
    }
    return m.relmse;
}

}  // namespace

int main(int argc, char** argv)
{
    int nthreads = 2, repeat = 3, tile = 1, converged_spp = 65536;
    std::string spp = "0064", only;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--threads") && i + 1 < argc)
            nthreads = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc)
            repeat = std::max(1, std::atoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--tile") && i + 1 < argc)
            tile = std::max(1, std::atoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--converged-spp") && i + 1 < argc)
            converged_spp = std::max(1, std::atoi(argv[++i]));
        else if (!std::strcmp(argv[i], "--only") && i + 1 < argc)
            only = argv[++i];
        else if (!std::strcmp(argv[i], "--spp") && i + 1 < argc) {
            spp = argv[++i];
            spp = std::string(4 - std::min<size_t>(4, spp.size()), '0') + spp;
        } else {
            std::fprintf(stderr, "usage: bench_skip [--spp 16|64|256] [--threads N] [--repeat N] "
                                 "[--only CHAIN] [--tile N] "
                                 "[--converged-spp N]\n");
            return 2;
        }
    }
    const std::string base = data("box/box_" + spp + "spp");
    if (!OIIO::Filesystem::exists(base + ".exr")
        || !OIIO::Filesystem::exists(data("box/box_ref_var.exr"))) {
        std::printf("bench_skip: %s.exr or the reference absent (no ../shared/data): skipped\n",
                    base.c_str());
        return 0;
    }
    ImageBuf noisy, ref, ref_var;
    if (!read_inputs(noisy, { { base + ".exr", InputKind::Mean },
                              { base + "_var.exr", InputKind::Variance },
                              { base + "_A.exr", InputKind::HalfA },
                              { base + "_B.exr", InputKind::HalfB } })
        || !read_image(ref, data("box/box_ref.exr"))
        || !read_image(ref_var, data("box/box_ref_var.exr"))) {
        std::fprintf(stderr, "bench_skip: %s %s\n", noisy.geterror().c_str(),
                     ref.geterror().c_str());
        return 1;
    }
    noisy = tiled(noisy, tile);
    ref = tiled(ref, tile);
    ref_var = tiled(ref_var, tile);
    const int width = noisy.spec().width;
    const ImageBuf half = converge_left(noisy, ref, ref_var, width / 2, 4096.0f / converged_spp);

    AovSpec aovs;
    aovs.preset = "cycles";
    AovSet set;
    std::string error;
    resolve_aovs(set, aovs, half.spec(), error);
    const ConvergedTiles map = converged_tiles_of(half, set, SkipOptions());
    const ConvergedTiles noisy_map = converged_tiles_of(noisy, set, SkipOptions());
    std::printf(
        "box %s spp, %dx%d, %d threads, best of %d; left half as from %d spp; converged tiles: "
        "half-converged frame %d of %d (left half: %d), all-noisy frame %d\n",
        spp.c_str(), width, noisy.spec().height, nthreads, repeat, converged_spp, map.count(),
        map.tiles_x * map.tiles_y, map.tiles_x * map.tiles_y / 2, noisy_map.count());

    auto nfor_chain = [&](bool skip) -> Chain {
        NforOptions o;
        o.aovs = o.prefilter.aovs = aovs;
        o.skip.enabled = skip;
        return [o, nthreads](ImageBuf& dst, const ImageBuf& src) {
            return nfor(dst, src, o, {}, nthreads);
        };
    };
    auto cnn_chain = [&](bool skip) -> Chain {
        CnnOptions o;
        o.aovs = aovs;
        o.skip.enabled = skip;
        return [o, nthreads](ImageBuf& dst, const ImageBuf& src) {
            return cnn(dst, src, o, {}, nthreads);
        };
    };
    auto mixed_chain = [&](bool skip, MixOptions::Model model) -> Chain {
        Chain denoiser = nfor_chain(skip);
        SureOptions s;
        s.aovs = aovs;
        s.skip.enabled = skip;
        MixOptions m;
        m.aovs = aovs;
        m.model = model;
        m.skip.enabled = skip;
        return [=](ImageBuf& dst, const ImageBuf& src) {
            ImageBuf with_error;
            if (!sure(with_error, src, denoiser, s, {}, nthreads)) {
                dst.errorfmt("{}", with_error.geterror());
                return false;
            }
            return mix(dst, with_error, m, {}, nthreads);
        };
    };
    struct Row {
        const char* name;
        std::function<Chain(bool)> make;
    };
    const Row rows[] = {
        { "nfor", nfor_chain },
        { "cnn", cnn_chain },
        { "nfor+sure+mix:analytic",
          [&](bool s) { return mixed_chain(s, MixOptions::Model::Analytic); } },
        { "nfor+sure+mix:net", [&](bool s) { return mixed_chain(s, MixOptions::Model::Net); } },
    };
    const std::vector<int> ref_rgb = { ref.spec().channelindex("ViewLayer.Combined.R"),
                                       ref.spec().channelindex("ViewLayer.Combined.G"),
                                       ref.spec().channelindex("ViewLayer.Combined.B") };
    const std::vector<int> rgb = set.channels(Role::Color);

    std::printf(
        "\n| chain | all noisy, skip on: CPU s (wall s) | half converged, skip on | half, skip off "
        "| ratio half/noisy, skip on: CPU (wall) | relMSE half, skip on / off: whole frame "
        "| noisy half | all noisy, skip on / off: whole frame "
        "|\n|---|---|---|---|---|---|---|---|\n");
    for (const Row& row : rows) {
        if (!only.empty() && only != row.name)
            continue;
        ImageBuf out_noisy, out_noisy_off, out_on, out_off;
        Timing t_noisy, t_on, t_off;
        // Interleaved, so that a change of the machine's load hits all three alike.
        for (int r = 0; r < repeat; ++r) {
            t_noisy = best(t_noisy, time_chain(row.make(true), noisy, out_noisy, 1));
            t_on = best(t_on, time_chain(row.make(true), half, out_on, 1));
            t_off = best(t_off, time_chain(row.make(false), half, out_off, 1));
        }
        time_chain(row.make(false), noisy, out_noisy_off, 1);
        std::printf(
            "| %s | %.2f (%.2f) | %.2f (%.2f) | %.2f (%.2f) | **%.2f** (%.2f) | %.5f / %.5f "
            "| %.5f / %.5f | %.5f / %.5f |\n",
            row.name, t_noisy.cpu, t_noisy.wall, t_on.cpu, t_on.wall, t_off.cpu, t_off.wall,
            t_on.cpu / t_noisy.cpu, t_on.wall / t_noisy.wall,
            relmse(out_on, rgb, ref, ref_rgb, 0, width),
            relmse(out_off, rgb, ref, ref_rgb, 0, width),
            relmse(out_on, rgb, ref, ref_rgb, width / 2, width),
            relmse(out_off, rgb, ref, ref_rgb, width / 2, width),
            relmse(out_noisy, rgb, ref, ref_rgb, 0, width),
            relmse(out_noisy_off, rgb, ref, ref_rgb, 0, width));
        std::fflush(stdout);
    }
    return 0;
}
