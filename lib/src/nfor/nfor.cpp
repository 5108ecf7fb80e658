// mcdn::nfor, reading like the paper: prefiltered features (§5.1), first pass of
// cross-filtered regressions for two bandwidths (§5.2), MSE estimate and bandwidth selection
// (§5.3), second pass on the averaged halves (§5.4).
#include "mcdn/nfor.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>

#include <sys/resource.h>

#include <OpenImageIO/imagebufalgo.h>

#include "core/channels.h"
#include "skip/constant_features.h"
#include "skip/converged_tiles.h"
#include "core/attributes.h"
#include "core/extra_aovs.h"
#include "core/feature_channels.h"
#include "nl_means/nl_means.h"
#include "core/bands.h"
#include "core/op_prepare.h"
#include "mcdn/color.h"
#include "nfor/extras_regression.h"
#include "nfor/mse_estimate.h"
#include "nfor/regression.h"
#include "prefilter/feature_prefilter.h"

namespace mcdn {
namespace {

bool check_options(ImageBuf& dst, const NforOptions& o)
{
    bool ok = o.window_radius >= 0 && o.patch_radius >= 0 && o.map_window_radius >= 0
              && o.map_patch_radius >= 0 && o.second_window_radius >= 0
              && o.second_patch_radius >= 0 && o.candidate_k[0] > 0 && o.candidate_k[1] > 0
              && o.map_k > 0 && o.second_k > 0 && o.variance_scale > 0;
    if (!ok)
        dst.errorfmt("nfor: window and patch radii must be >= 0 and every k > 0 (window {}, "
                     "patch {}, k {} and {})", o.window_radius, o.patch_radius,
                     o.candidate_k[0], o.candidate_k[1]);
    return ok;
}

/// Process CPU seconds, all threads (the stage times on a shared machine).
double process_cpu_seconds()
{
    rusage u {};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

/// MCDN_TRACE=1 prints the wall and CPU time of each stage to stderr (for the benchmark).
struct StageTimer {
    bool on = std::getenv("MCDN_TRACE") != nullptr;
    std::chrono::steady_clock::time_point last = std::chrono::steady_clock::now();
    double last_cpu = on ? process_cpu_seconds() : 0.0;
    void operator()(const char* stage)
    {
        auto now = std::chrono::steady_clock::now();
        if (on) {
            double cpu = process_cpu_seconds();
            std::fprintf(stderr, "nfor: %-28s %7.3f s wall %7.3f s CPU\n", stage,
                         std::chrono::duration<double>(now - last).count(), cpu - last_cpu);
            last_cpu = cpu;
        }
        last = now;
    }
};

/// The colour role's four faces as planes: mean, variance of the mean, halves A and B.
struct ColorPlanes {
    Plane mean[3], variance[3], half_a[3], half_b[3];
};

}  // namespace

namespace {

bool nfor_in_working_space(ImageBuf& dst, const ImageBuf& src, const NforOptions& options,
                         ROI roi, int nthreads)
{
    const char* op = "nfor";
    if (!check_options(dst, options))
        return false;
    AovSet aovs;
    std::string error;
    std::vector<FeatureChannel> feature_channels;
    if (!resolve_aovs(aovs, options.aovs, src.spec(), error)
        || !aovs.require({ Role::Color, Role::ColorA, Role::ColorB }, src.spec(), error)
        || !find_feature_channels(feature_channels, aovs, src.spec(), options.extra_features, op,
                                  error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    if (int(feature_channels.size()) > kMaxRegressionFeatures) {
        dst.errorfmt("nfor: {} feature channels, at most {} are supported; drop extra features",
                     feature_channels.size(), kMaxRegressionFeatures);
        return false;
    }
    for (Role role : { Role::Color, Role::ColorA, Role::ColorB, Role::ColorVariance })
        if (aovs.has(role) && aovs.channels(role).size() != 3) {
            dst.errorfmt("nfor: role {} needs 3 channels, got {}", role_name(role),
                         aovs.channels(role).size());
            return false;
        }

    StageTimer timer;
    // Read everything the filter needs before dst (which may be src) is written.
    ColorPlanes color;
    for (int c = 0; c < 3; ++c) {
        color.mean[c] = read_plane(src, aovs.channels(Role::Color)[c]);
        color.half_a[c] = read_plane(src, aovs.channels(Role::ColorA)[c]);
        color.half_b[c] = read_plane(src, aovs.channels(Role::ColorB)[c]);
        if (aovs.has(Role::ColorVariance)) {
            color.variance[c] = read_plane(src, aovs.channels(Role::ColorVariance)[c], true);
        } else {  // two-buffer estimate of the variance of the mean
            color.variance[c] = Plane(src.spec().width, src.spec().height);
            for (size_t i = 0; i < color.variance[c].size(); ++i) {
                float d = color.half_a[c].px[i] - color.half_b[c].px[i];
                color.variance[c].px[i] = sanitize_variance(0.25f * d * d);
            }
        }
    }
    std::vector<FeaturePlanes> features;
    for (const FeatureChannel& f : feature_channels)
        features.push_back(read_feature(src, f));
    std::vector<ExtraPlanes> extra_planes;
    if (denoises_extras(options.denoise_extras, src)
        && !read_extras(extra_planes, src, aovs, true, error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    // Extra AOVs go through the beauty's filters stage by stage (nfor/extras_regression.h).
    ExtraAovs extras(std::move(extra_planes));
    // mcdn/skip.h: converged tiles pass through every stage below; constant features go.
    const ConvergedTiles converged = converged_tiles_of(src, color.mean, color.variance, options.skip);
    if (options.skip.enabled)
        drop_constant_features(features);

    // §5.1: prefiltered features, unless the prefilter op ran already.
    const bool prefiltered = src.spec().get_int_attribute("mcdn:prefiltered", 0) == 1;
    timer("read planes");
    if (!prefiltered && options.prefilter_features)
        prefilter_planes(features, options.prefilter, nthreads, &converged);
    // Planes are freed as soon as their last stage is done (peak memory at 1080p).
    for (FeaturePlanes& f : features)
        f.variance = Plane();
    timer("prefilter (5.1)");

    std::vector<const Plane*> features_a, features_b, features_mean;
    for (const FeaturePlanes& f : features) {
        features_a.push_back(&f.half_a);
        features_b.push_back(&f.half_b);
        features_mean.push_back(&f.mean);
    }

    // §5.2: half A fitted with the features and colour weights of half B, and vice versa,
    // for each candidate bandwidth; §5.3: the two-buffer MSE estimate of each candidate.
    RegressionInputs first_a, first_b;
    first_a.window_radius = options.window_radius;
    first_a.patch_radius = options.patch_radius;
    first_a.bandwidths = { options.candidate_k[0], options.candidate_k[1] };
    first_a.variance_scale = options.variance_scale;
    first_a.skip_tiles = &converged;
    first_b = first_a;
    for (int c = 0; c < 3; ++c) {
        first_a.image[c] = &color.half_a[c];
        first_a.guide[c] = &color.half_b[c];
        first_b.image[c] = &color.half_b[c];
        first_b.guide[c] = &color.half_a[c];
        first_a.variance[c] = first_b.variance[c] = &color.variance[c];
    }
    first_a.features = features_b;
    first_b.features = features_a;
    std::vector<Plane> fit_a[2], fit_b[2], mse[2];
    {
        std::vector<std::vector<Plane>> fits = collaborative_regression(first_a, nthreads);
        fit_a[0] = std::move(fits[0]);
        fit_a[1] = std::move(fits[1]);
        fits = collaborative_regression(first_b, nthreads);
        fit_b[0] = std::move(fits[0]);
        fit_b[1] = std::move(fits[1]);
    }
    extras.first_pass(first_a, first_b, nthreads);
    for (FeaturePlanes& f : features) {
        f.half_a = Plane();
        f.half_b = Plane();
    }
    timer("first pass regressions (5.2)");
    for (int j = 0; j < 2; ++j) {
        const Plane* half_a[3] = { &color.half_a[0], &color.half_a[1], &color.half_a[2] };
        const Plane* half_b[3] = { &color.half_b[0], &color.half_b[1], &color.half_b[2] };
        const Plane* variance[3] = { &color.variance[0], &color.variance[1], &color.variance[2] };
        mse[j] = estimate_mse(half_a, half_b, variance, fit_a[j], fit_b[j]);
    }
    for (int c = 0; c < 3; ++c) {
        color.half_a[c] = Plane();
        color.half_b[c] = Plane();
    }

    // §5.3: filter the MSE estimates (NL-means on the mean colour), pick the lower per
    // pixel, filter the selection map the same way, blend the candidates with it.
    const NlMeansParams map_params { options.map_patch_radius, options.map_window_radius,
                                     options.map_k, 1.0f };
    std::vector<const Plane*> map_guide, map_variance, noisy;
    for (int c = 0; c < 3; ++c) {
        map_guide.push_back(&color.mean[c]);
        map_variance.push_back(&color.variance[c]);
    }
    for (int j = 0; j < 2; ++j)
        for (int c = 0; c < 3; ++c)
            noisy.push_back(&mse[j][c]);
    std::vector<Plane> filtered_mse = nl_means(noisy, map_guide, map_variance, map_params, nthreads, &converged);
    for (int j = 0; j < 2; ++j)
        mse[j].clear();
    std::vector<Plane> mse0(std::make_move_iterator(filtered_mse.begin()),
                            std::make_move_iterator(filtered_mse.begin() + 3));
    std::vector<Plane> mse1(std::make_move_iterator(filtered_mse.begin() + 3),
                            std::make_move_iterator(filtered_mse.end()));
    filtered_mse.clear();
    std::vector<Plane> selection_noisy = select_candidate(mse0, mse1);
    noisy.clear();
    for (int c = 0; c < 3; ++c)
        noisy.push_back(&selection_noisy[c]);
    std::vector<Plane> selection = nl_means(noisy, map_guide, map_variance, map_params, nthreads, &converged);
    selection_noisy.clear();
    for (int c = 0; c < 3; ++c)
        color.variance[c] = Plane();

    timer("MSE + selection maps (5.3)");
    Plane combined[3], combined_variance[3];
    for (int c = 0; c < 3; ++c) {
        combined[c] = Plane(src.spec().width, src.spec().height);
        combined_variance[c] = combined[c];
        for (size_t i = 0; i < combined[c].size(); ++i) {
            float s = selection[c].px[i];
            float a = blend_candidates(fit_a, c, i, s);
            float b = blend_candidates(fit_b, c, i, s);
            // §5.4: the second pass filters the average of the halves, whose variance the
            // halves' squared difference estimates.
            combined[c].px[i] = 0.5f * (a + b);
            combined_variance[c].px[i] = sanitize_variance(0.25f * (b - a) * (b - a));
            mse0[c].px[i] = mse0[c].px[i] + s * (mse1[c].px[i] - mse0[c].px[i]);
        }
    }
    extras.blend(selection);
    for (int j = 0; j < 2; ++j) {
        fit_a[j].clear();
        fit_b[j].clear();
    }
    mse1.clear();
    if (!options.output_mse)
        mse0.clear();
    if (!options.output_selection)
        selection.clear();

    // §5.4: second pass, guided by and fitted to the combined result, mean features.
    RegressionInputs second;
    second.window_radius = options.second_window_radius;
    second.patch_radius = options.second_patch_radius;
    second.bandwidths = { options.second_k };
    second.variance_scale = options.variance_scale;
    second.skip_tiles = &converged;
    for (int c = 0; c < 3; ++c) {
        second.image[c] = &combined[c];
        second.guide[c] = &combined[c];
        second.variance[c] = &combined_variance[c];
    }
    second.features = features_mean;
    timer("blend");
    std::vector<Plane> denoised = std::move(collaborative_regression(second, nthreads)[0]);
    extras.second_pass(second, nthreads);
    for (int c = 0; c < 3; ++c) {
        combined[c] = Plane();
        combined_variance[c] = Plane();
    }
    features.clear();
    timer("second pass (5.4)");

    // Nothing non-finite leaves the op (the regression already falls back per pixel).
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < denoised[c].size(); ++i)
            if (!std::isfinite(denoised[c].px[i]))
                denoised[c].px[i] = color.mean[c].px[i];
    for (int c = 0; c < 3; ++c)
        pass_through_converged(denoised[c], color.mean[c], converged);

    // dst (a copy of src) is made only now, when the working planes are gone; everything was
    // read from src before (dst may be src).
    if (!prepare_op(dst, src, options.aovs, aovs, op))
        return false;
    timer("copy src to dst");
    roi = output_roi(dst, roi);
    for (int c = 0; c < 3; ++c)
        write_plane(dst, aovs.channels(Role::Color)[c], denoised[c], roi);

    // The extras' sum stays the denoised beauty.
    if (!extras.empty()) {
        extras.share_rounding(color.mean, denoised);
        extras.pass_through(converged);
        extras.write(dst, roi);
    }

    if (options.output_mse || options.output_selection) {
        std::vector<std::string> names;
        if (options.output_mse)
            for (const char* n : { "nfor.mse.R", "nfor.mse.G", "nfor.mse.B" })
                names.push_back(n);
        if (options.output_selection)
            for (const char* n : { "nfor.selection.R", "nfor.selection.G", "nfor.selection.B" })
                names.push_back(n);
        const std::vector<int> new_index = add_channels(dst, names);
        if (std::find(new_index.begin(), new_index.end(), -1) != new_index.end()) {
            dst.errorfmt("nfor: could not add the nfor.* output channels");
            return false;
        }
        size_t n = 0;
        if (options.output_mse)
            for (int c = 0; c < 3; ++c, ++n) {
                for (float& v : mse0[c].px)
                    v = sanitize(v);
                write_plane(dst, new_index[n], mse0[c], roi);
            }
        if (options.output_selection)
            for (int c = 0; c < 3; ++c, ++n)
                write_plane(dst, new_index[n], selection[c], roi);
    }
    timer("write");
    return true;
}

}  // namespace

// How far NFOR reaches, stage by stage: the feature prefilter (two NL-means steps, unless it
// ran already); a collaborative pass (an output pixel averages the fits of every window that
// holds it, each fit weighted by patches around its window: 2 windows + 1 patch); the two
// NL-means filters of the MSE and selection maps (§5.3); the second collaborative pass.
int receptive_radius(const NforOptions& o, bool prefiltered)
{
    const PrefilterOptions& p = o.prefilter;
    int prefilter = prefiltered || !o.prefilter_features
                        ? 0
                        : p.window_radius + p.patch_radius + p.second_window_radius
                              + p.second_patch_radius;
    return prefilter + 2 * o.window_radius + o.patch_radius
           + 2 * (o.map_window_radius + o.map_patch_radius) + 2 * o.second_window_radius
           + o.second_patch_radius;
}

bool nfor(ImageBuf& dst, const ImageBuf& src, const NforOptions& options, ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "nfor"))
        return false;
    bool prefiltered = src.spec().get_int_attribute("mcdn:prefiltered", 0) == 1;
    if (!run_local_op(dst, src, options.aovs, "nfor", receptive_radius(options, prefiltered),
                      options.band_pixels, [&](ImageBuf& d, const ImageBuf& s) {
                          return nfor_in_working_space(d, s, options, roi, nthreads);
                      }))
        return false;
    dst.specmod().attribute(kDenoiserAttribute, "nfor");
    return true;
}

ImageBuf nfor(const ImageBuf& src, const NforOptions& options, ROI roi, int nthreads)
{
    ImageBuf dst;
    nfor(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
