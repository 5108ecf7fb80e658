// NFOR benchmark: accuracy and speed on ../shared/data, against the reference implementation.
//
//   bench_nfor [--threads N] [--repeat N] [--only NAME] [--hd]
//
// For every input: relMSE and SMAPE of the noisy input, of our prefilter+nfor, and of the
// reference NFOR output (nfor-reference/); our wall time, and that time as a ratio to
//   - the reference implementation (6.3-7.5 s at 256×256 with 2 threads, data README) and
//   - an in-run baseline: OIIO's ImageBufAlgo::convolve of the RGB colour with a 19×19
//     box kernel (361 multiply-adds per pixel and channel) timed in the same run, so the
//     ratio survives a busy machine;
// and the FLOP rate from the op's FLOP model. --hd runs a 1920×1080 frame (the box 64 spp
// image tiled) and prints the peak RSS.
#include <chrono>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include <sys/resource.h>

#include <OpenImageIO/imagebufalgo.h>

#include "mcdn/io.h"
#include "mcdn/metrics.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "core/simd.h"
#include "nfor/regression.h"

using namespace mcdn;
using Clock = std::chrono::steady_clock;

namespace {

struct Input {
    const char* name;
    std::vector<InputFile> files;
    const char* preset;
    std::string reference, nfor_reference;
    double table_relmse;  // the README's yardstick for the reference implementation
};

std::string data(const std::string& rel)
{
    return std::string(MCDN_SHARED_DATA) + "/" + rel;
}

std::vector<Input> inputs()
{
    std::vector<Input> list;
    const char* spp[] = { "0016", "0064", "0256" };
    const double table[] = { 0.00968, 0.00271, 0.00158 };
    for (int i = 0; i < 3; ++i) {
        std::string base = data(std::string("box/box_") + spp[i] + "spp");
        list.push_back({ spp[i] == std::string("0016")   ? "box 16"
                         : spp[i] == std::string("0064") ? "box 64"
                                                         : "box 256",
                         { { base + ".exr", InputKind::Mean },
                           { base + "_var.exr", InputKind::Variance },
                           { base + "_A.exr", InputKind::HalfA },
                           { base + "_B.exr", InputKind::HalfB } },
                         "cycles",
                         data("box/box_ref.exr"),
                         data(std::string("box/nfor-reference/box_") + spp[i] + "spp_nfor.exr"),
                         table[i] });
    }
    list.push_back({ "cornell20",
                     { { data("tungsten/cornell20"), InputKind::Mean } },
                     "tungsten",
                     data("tungsten/cornell20/ref.pfm"),
                     data("tungsten/cornell20/nfor-reference/nfor.pfm"),
                     0.00075 });
    list.push_back({ "materialtest",
                     { { data("tungsten/materialtest"), InputKind::Mean } },
                     "tungsten",
                     data("tungsten/materialtest/ref.pfm"),
                     data("tungsten/materialtest/nfor-reference/nfor.pfm"),
                     0.00433 });
    return list;
}

double seconds_since(Clock::time_point t0)
{
    return std::chrono::duration<double>(Clock::now() - t0).count();
}

/// The in-run baseline: 19×19 box convolution of three channels (OIIO IBA).
double baseline_seconds(const ImageBuf& src, const std::vector<int>& rgb, int nthreads)
{
    ImageBuf color = OIIO::ImageBufAlgo::channels(src, 3, rgb);
    ImageBuf kernel = OIIO::ImageBufAlgo::make_kernel("box", 19, 19);
    double best = 1e30;
    for (int r = 0; r < 3; ++r) {
        auto t0 = Clock::now();
        ImageBuf out = OIIO::ImageBufAlgo::convolve(color, kernel, true, {}, nthreads);
        best = std::min(best, seconds_since(t0));
    }
    return best;
}

bool metrics_of(Metrics& m, const ImageBuf& image, const std::vector<int>& channels,
                const std::string& reference_path)
{
    ImageBuf ref;
    if (!read_image(ref, reference_path))
        return false;
    MetricsOptions mo;
    mo.image_channels = channels;
    mo.reference_channels = { 0, 1, 2 };
    std::string error;
    if (!compute_metrics(m, image, ref, mo, error)) {
        std::fprintf(stderr, "metrics: %s\n", error.c_str());
        return false;
    }
    return true;
}

double flops_per_pixel(int nf, const NforOptions& o, const PrefilterOptions& p)
{
    auto nlm = [](int channels, int R, int F) {
        double n = (2 * R + 1) * (2 * R + 1);
        return n * channels * (9.0 + 2 * (2 * F + 1) + 20 + 3);
    };
    double f = 4 * regression_flops_per_pixel(nf, o.window_radius, o.patch_radius)
               + regression_flops_per_pixel(nf, o.second_window_radius, o.second_patch_radius);
    f += nlm(2 * nf, p.window_radius, p.patch_radius)
         + nlm(nf, p.second_window_radius, p.second_patch_radius);
    f += nlm(3, o.map_window_radius, o.map_patch_radius)
         * 2;  // MSE (6 images, 3 weights) + selection
    return f;
}

/// User + system CPU seconds of the whole process (all threads).
double cpu_seconds()
{
    rusage u {};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

long peak_rss_mb()
{
    rusage u {};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_maxrss / 1024;
}

}  // namespace

int main(int argc, char** argv)
{
    int nthreads = 2, repeat = 3;
    std::string only;
    bool hd = false;
    for (int i = 1; i < argc; ++i) {
        if (!std::strcmp(argv[i], "--threads") && i + 1 < argc)
            nthreads = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--repeat") && i + 1 < argc)
            repeat = std::atoi(argv[++i]);
        else if (!std::strcmp(argv[i], "--only") && i + 1 < argc)
            only = argv[++i];
        else if (!std::strcmp(argv[i], "--hd"))
            hd = true;
    }

    if (hd) {
        // 1920×1080: the box 64 spp input tiled 8×5 and cropped; only the channels NFOR reads.
        ImageBuf merged;
        Input in = inputs()[1];
        if (!read_inputs(merged, in.files)) {
            std::fprintf(stderr, "%s\n", merged.geterror().c_str());
            return 1;
        }
        AovSet aovs;
        AovSpec spec;
        std::string error;
        resolve_aovs(aovs, spec, merged.spec(), error);
        std::vector<int> keep;
        for (Role r : { Role::Color, Role::ColorVariance, Role::ColorA, Role::ColorB, Role::Albedo,
                        Role::AlbedoVariance, Role::AlbedoA, Role::AlbedoB, Role::Normal,
                        Role::NormalVariance, Role::NormalA, Role::NormalB, Role::Depth,
                        Role::DepthVariance, Role::DepthA, Role::DepthB })
            for (int c : aovs.channels(r))
                keep.push_back(c);
        ImageBuf small = OIIO::ImageBufAlgo::channels(merged, int(keep.size()), keep);
        merged.reset();
        // Time against pixel count (the op is linear in it) and the peak RSS at 1080p.
        std::printf("| size | pixels | wall s | CPU s | CPU us/pixel | peak RSS MB |\n"
                    "|---|---:|---:|---:|---:|---:|\n");
        const int sizes[][2] = { { 256, 256 }, { 512, 512 }, { 1920, 1080 } };
        for (const auto& size : sizes) {
            ImageSpec hs = small.spec();
            hs.width = hs.full_width = size[0];
            hs.height = hs.full_height = size[1];
            ImageBuf big(hs);
            for (int ty = 0; ty < size[1]; ty += 256)
                for (int tx = 0; tx < size[0]; tx += 256)
                    OIIO::ImageBufAlgo::paste(big, tx, ty, 0, 0, small);
            auto t0 = Clock::now();
            double c0 = cpu_seconds();
            ImageBuf out = nfor(big, NforOptions {}, {}, nthreads);
            double t = seconds_since(t0), cpu = cpu_seconds() - c0;
            if (out.has_error())
                std::fprintf(stderr, "%s\n", out.geterror().c_str());
            const double pixels = double(size[0]) * size[1];
            std::printf("| %dx%d | %.0f | %.2f | %.2f | %.2f | %ld |\n", size[0], size[1], pixels,
                        t, cpu, cpu / pixels * 1e6, peak_rss_mb());
            std::fflush(stdout);
        }
        std::printf("\n%d threads; %zu input channels (the ones NFOR reads); peak RSS is the "
                    "process's maximum so far (the 1080p row is the 1080p peak).\n",
                    nthreads, keep.size());
        return 0;
    }

    std::printf("mcdenoise NFOR benchmark (prefilter + nfor), %d thread(s), best of %d, ISA %s\n\n",
                nthreads, repeat, isa_name(detect_isa()));
    std::printf("| input | relMSE noisy | relMSE ours | relMSE ref-impl | ours/ref | SMAPE ours | "
                "SMAPE ref | wall s | CPU s | speed-up (wall) | speed-up (CPU/%d) | /base | "
                "GFLOP/s |\n",
                nthreads);
    std::printf("|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for (const Input& in : inputs()) {
        if (!only.empty() && only != in.name)
            continue;
        ImageBuf merged;
        if (!read_inputs(merged, in.files)) {
            std::fprintf(stderr, "%s: %s\n", in.name, merged.geterror().c_str());
            continue;
        }
        NforOptions options;
        options.aovs.preset = in.preset;
        AovSet aovs;
        std::string error;
        resolve_aovs(aovs, options.aovs, merged.spec(), error);
        const std::vector<int>& rgb = aovs.channels(Role::Color);
        int nf = 0;
        for (Role r : { Role::Albedo, Role::Normal, Role::Depth, Role::Visibility })
            nf += int(aovs.channels(r).size());

        double best = 1e30, best_cpu = 1e30;
        ImageBuf out;
        for (int r = 0; r < repeat; ++r) {
            auto t0 = Clock::now();
            double c0 = cpu_seconds();
            // nfor prefilters the features itself (§5.1) on its planes: the same result as
            // prefilter then nfor, without the round trip through a 156-channel image.
            out = nfor(merged, options, {}, nthreads);
            best = std::min(best, seconds_since(t0));
            best_cpu = std::min(best_cpu, cpu_seconds() - c0);
            if (out.has_error()) {
                std::fprintf(stderr, "%s: %s\n", in.name, out.geterror().c_str());
                return 1;
            }
        }
        double base = baseline_seconds(merged, rgb, nthreads);
        Metrics noisy, ours, refimpl;
        metrics_of(noisy, merged, rgb, in.reference);
        metrics_of(ours, out, rgb, in.reference);
        ImageBuf refout;
        read_image(refout, in.nfor_reference);
        metrics_of(refimpl, refout, { 0, 1, 2 }, in.reference);
        const double pixels = double(merged.spec().width) * merged.spec().height;
        const double scale = pixels / (256.0 * 256.0);
        double gflops = flops_per_pixel(nf, options, PrefilterOptions {}) * pixels / best * 1e-9;
        // Speed-up over the reference's 6.3-7.5 s (2 threads, idle machine): from our wall
        // time, and from our CPU time / threads (what the wall time would be on an idle
        // machine with perfect scaling; robust to other load on the machine).
        const double idle = best_cpu / nthreads;
        std::printf("| %s | %.5f | %.5f | %.5f | %.3f | %.4f | %.4f | %.3f | %.3f | %.1f-%.1fx | "
                    "%.1f-%.1fx | %.2f | %.1f |\n",
                    in.name, noisy.relmse, ours.relmse, refimpl.relmse,
                    ours.relmse / refimpl.relmse, ours.smape, refimpl.smape, best, best_cpu,
                    6.3 * scale / best, 7.5 * scale / best, 6.3 * scale / idle, 7.5 * scale / idle,
                    best / base, gflops);
        std::fflush(stdout);
    }
    std::printf(
        "\nrelMSE against the reference image: noisy input, ours (prefilter + nfor), the "
        "reference implementation's output (nfor-reference/). Speed-up: the reference's "
        "6.3-7.5 s (2 threads, idle machine) over our wall time, and over our CPU time / "
        "threads. /base: our wall time over the in-run 19x19 IBA box convolution of the "
        "colour (same run, same threads). GFLOP/s by the op's FLOP model. Peak RSS %ld MB.\n",
        peak_rss_mb());
    return 0;
}
