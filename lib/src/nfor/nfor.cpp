// mcdn::nfor, reading like the paper: prefiltered features (§5.1), first pass of
// cross-filtered regressions for two bandwidths (§5.2), MSE estimate and bandwidth selection
// (§5.3), second pass on the averaged halves (§5.4).
#include "mcdn/nfor.h"

#include <algorithm>

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
#include "core/trace.h"
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

/// The colour role's four faces as planes: mean, variance of the mean, halves A and B.
struct ColorPlanes {
    Plane mean[3], variance[3], half_a[3], half_b[3];
};

/// What the op reads from src before anything is written (dst may be src).
struct NforInputs {
    AovSet aovs;
    ColorPlanes color;
    std::vector<FeaturePlanes> features;
    std::vector<ExtraPlanes> extras;
};

bool read_inputs(NforInputs& in, ImageBuf& dst, const ImageBuf& src, const NforOptions& options)
{
    const char* op = "nfor";
    std::string error;
    std::vector<FeatureChannel> feature_channels;
    if (!resolve_aovs(in.aovs, options.aovs, src.spec(), error)
        || !in.aovs.require({ Role::Color, Role::ColorA, Role::ColorB }, src.spec(), error)
        || !find_feature_channels(feature_channels, in.aovs, src.spec(), options.extra_features,
                                  op, error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    if (int(feature_channels.size()) > kMaxRegressionFeatures) {
        dst.errorfmt("nfor: {} feature channels, at most {} are supported; drop extra features",
                     feature_channels.size(), kMaxRegressionFeatures);
        return false;
    }
    for (Role role : { Role::Color, Role::ColorA, Role::ColorB, Role::ColorVariance })
        if (in.aovs.has(role) && in.aovs.channels(role).size() != 3) {
            dst.errorfmt("nfor: role {} needs 3 channels, got {}", role_name(role),
                         in.aovs.channels(role).size());
            return false;
        }
    ColorPlanes& color = in.color;
    for (int c = 0; c < 3; ++c) {
        color.mean[c] = read_plane(src, in.aovs.channels(Role::Color)[c]);
        color.half_a[c] = read_plane(src, in.aovs.channels(Role::ColorA)[c]);
        color.half_b[c] = read_plane(src, in.aovs.channels(Role::ColorB)[c]);
        if (in.aovs.has(Role::ColorVariance)) {
            color.variance[c] = read_plane(src, in.aovs.channels(Role::ColorVariance)[c], true);
        } else {  // two-buffer estimate of the variance of the mean
            color.variance[c] = Plane(src.spec().width, src.spec().height);
            for (size_t i = 0; i < color.variance[c].size(); ++i) {
                float d = color.half_a[c].px[i] - color.half_b[c].px[i];
                color.variance[c].px[i] = sanitize_variance(0.25f * d * d);
            }
        }
    }
    for (const FeatureChannel& f : feature_channels)
        in.features.push_back(read_feature(src, f));
    if (denoises_extras(options.denoise_extras, src)
        && !read_extras(in.extras, src, in.aovs, true, error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    return true;
}

/// §5.1: the features' halves and mean NL-means filtered (unless the prefilter op ran
/// already); their variances are not needed after it.
void prefilter_features(std::vector<FeaturePlanes>& features, const NforOptions& options,
                        bool prefiltered, const ConvergedTiles& converged, int nthreads)
{
    if (!prefiltered && options.prefilter_features)
        prefilter_planes(features, options.prefilter, nthreads, &converged);
    for (FeaturePlanes& f : features)
        f.variance = Plane();
}

/// §5.2's cross-filtered fits of each half for both candidate bandwidths.
struct FirstPass {
    std::vector<Plane> fit_a[2], fit_b[2];
};

/// §5.2: half A fitted with the features and colour weights of half B, and vice versa, for
/// each candidate bandwidth. The features' halves are not needed after it.
FirstPass first_pass(const ColorPlanes& color, std::vector<FeaturePlanes>& features,
                     ExtraAovs& extras, const NforOptions& options,
                     const ConvergedTiles& converged, int nthreads)
{
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
    for (const FeaturePlanes& f : features) {
        first_a.features.push_back(&f.half_b);
        first_b.features.push_back(&f.half_a);
    }
    FirstPass pass;
    std::vector<std::vector<Plane>> fits = collaborative_regression(first_a, nthreads);
    pass.fit_a[0] = std::move(fits[0]);
    pass.fit_a[1] = std::move(fits[1]);
    fits = collaborative_regression(first_b, nthreads);
    pass.fit_b[0] = std::move(fits[0]);
    pass.fit_b[1] = std::move(fits[1]);
    extras.first_pass(first_a, first_b, nthreads);
    for (FeaturePlanes& f : features) {
        f.half_a = Plane();
        f.half_b = Plane();
    }
    return pass;
}

/// §5.3's result: the candidates blended per pixel, which is what §5.4 filters, and the
/// blended MSE estimate and selection map when asked for.
struct Selected {
    Plane combined[3], combined_variance[3];
    std::vector<Plane> mse, selection;
};

/// §5.3: the two-buffer MSE estimate of each candidate, NL-means filtered on the mean colour;
/// the lower one picked per pixel; that selection map filtered the same way and the
/// candidates blended with it. Consumes the fits and the colour's halves and variance.
Selected select_bandwidths(ColorPlanes& color, FirstPass& pass, ExtraAovs& extras,
                           const NforOptions& options, const ConvergedTiles& converged,
                           int nthreads)
{
    std::vector<Plane> mse[2];
    for (int j = 0; j < 2; ++j) {
        const Plane* half_a[3] = { &color.half_a[0], &color.half_a[1], &color.half_a[2] };
        const Plane* half_b[3] = { &color.half_b[0], &color.half_b[1], &color.half_b[2] };
        const Plane* variance[3] = { &color.variance[0], &color.variance[1], &color.variance[2] };
        mse[j] = estimate_mse(half_a, half_b, variance, pass.fit_a[j], pass.fit_b[j]);
    }
    for (int c = 0; c < 3; ++c) {
        color.half_a[c] = Plane();
        color.half_b[c] = Plane();
    }

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
    std::vector<Plane> filtered_mse = nl_means(noisy, map_guide, map_variance, map_params,
                                               nthreads, &converged);
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
    Selected out;
    out.selection = nl_means(noisy, map_guide, map_variance, map_params, nthreads, &converged);
    selection_noisy.clear();
    for (int c = 0; c < 3; ++c)
        color.variance[c] = Plane();

    const std::vector<Plane>& selection = out.selection;
    for (int c = 0; c < 3; ++c) {
        out.combined[c] = Plane(color.mean[c].width, color.mean[c].height);
        out.combined_variance[c] = out.combined[c];
        for (size_t i = 0; i < out.combined[c].size(); ++i) {
            float s = selection[c].px[i];
            float a = blend_candidates(pass.fit_a, c, i, s);
            float b = blend_candidates(pass.fit_b, c, i, s);
            // §5.4 filters the average of the halves, whose variance the halves' squared
            // difference estimates.
            out.combined[c].px[i] = 0.5f * (a + b);
            out.combined_variance[c].px[i] = sanitize_variance(0.25f * (b - a) * (b - a));
            mse0[c].px[i] = mse0[c].px[i] + s * (mse1[c].px[i] - mse0[c].px[i]);
        }
    }
    extras.blend(selection);
    for (int j = 0; j < 2; ++j) {
        pass.fit_a[j].clear();
        pass.fit_b[j].clear();
    }
    mse1.clear();
    if (options.output_mse)
        out.mse = std::move(mse0);
    if (!options.output_selection)
        out.selection.clear();
    return out;
}

/// §5.4: the combined halves filtered once more, guided by themselves, with the mean
/// features. Consumes the combined planes and the features.
std::vector<Plane> second_pass(Selected& selected, std::vector<FeaturePlanes>& features,
                               ExtraAovs& extras, const NforOptions& options,
                               const ConvergedTiles& converged, int nthreads)
{
    RegressionInputs second;
    second.window_radius = options.second_window_radius;
    second.patch_radius = options.second_patch_radius;
    second.bandwidths = { options.second_k };
    second.variance_scale = options.variance_scale;
    second.skip_tiles = &converged;
    for (int c = 0; c < 3; ++c) {
        second.image[c] = &selected.combined[c];
        second.guide[c] = &selected.combined[c];
        second.variance[c] = &selected.combined_variance[c];
    }
    for (const FeaturePlanes& f : features)
        second.features.push_back(&f.mean);
    std::vector<Plane> denoised = std::move(collaborative_regression(second, nthreads)[0]);
    extras.second_pass(second, nthreads);
    for (int c = 0; c < 3; ++c) {
        selected.combined[c] = Plane();
        selected.combined_variance[c] = Plane();
    }
    features.clear();
    return denoised;
}

/// The nfor.mse.* and nfor.selection.* channels, when asked for.
bool write_maps(ImageBuf& dst, Selected& selected, ROI roi)
{
    std::vector<std::string> names;
    if (!selected.mse.empty())
        for (const char* n : { "nfor.mse.R", "nfor.mse.G", "nfor.mse.B" })
            names.push_back(n);
    if (!selected.selection.empty())
        for (const char* n : { "nfor.selection.R", "nfor.selection.G", "nfor.selection.B" })
            names.push_back(n);
    if (names.empty())
        return true;
    const std::vector<int> new_index = add_channels(dst, names);
    if (std::find(new_index.begin(), new_index.end(), -1) != new_index.end()) {
        dst.errorfmt("nfor: could not add the nfor.* output channels");
        return false;
    }
    size_t n = 0;
    for (int c = 0; c < int(selected.mse.size()); ++c, ++n) {
        for (float& v : selected.mse[c].px)
            v = sanitize(v);
        write_plane(dst, new_index[n], selected.mse[c], roi);
    }
    for (int c = 0; c < int(selected.selection.size()); ++c, ++n)
        write_plane(dst, new_index[n], selected.selection[c], roi);
    return true;
}

bool nfor_in_working_space(ImageBuf& dst, const ImageBuf& src, const NforOptions& options,
                           ROI roi, int nthreads)
{
    if (!check_options(dst, options))
        return false;
    StageTrace trace("nfor");
    NforInputs in;
    if (!read_inputs(in, dst, src, options))
        return false;
    ColorPlanes& color = in.color;
    // Extra AOVs go through the beauty's filters stage by stage (nfor/extras_regression.h).
    ExtraAovs extras(std::move(in.extras));
    // mcdn/skip.h: converged tiles pass through every stage below; constant features go.
    const ConvergedTiles converged = converged_tiles_of(src, color.mean, color.variance,
                                                        options.skip);
    if (options.skip.enabled)
        drop_constant_features(in.features);
    trace.mark("read planes");

    const bool prefiltered = src.spec().get_int_attribute("mcdn:prefiltered", 0) == 1;
    prefilter_features(in.features, options, prefiltered, converged, nthreads);
    trace.mark("prefilter (5.1)");
    FirstPass pass = first_pass(color, in.features, extras, options, converged, nthreads);
    trace.mark("first pass regressions (5.2)");
    Selected selected = select_bandwidths(color, pass, extras, options, converged, nthreads);
    trace.mark("MSE + selection maps (5.3)");
    std::vector<Plane> denoised = second_pass(selected, in.features, extras, options,
                                              converged, nthreads);
    trace.mark("second pass (5.4)");

    // Nothing non-finite leaves the op (the regression already falls back per pixel).
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < denoised[c].size(); ++i)
            if (!std::isfinite(denoised[c].px[i]))
                denoised[c].px[i] = color.mean[c].px[i];
    for (int c = 0; c < 3; ++c)
        pass_through_converged(denoised[c], color.mean[c], converged);

    // dst (a copy of src) is made only now, when the working planes are gone; everything was
    // read from src before (dst may be src).
    if (!prepare_op(dst, src, options.aovs, in.aovs, "nfor"))
        return false;
    trace.mark("copy src to dst");
    roi = output_roi(dst, roi);
    for (int c = 0; c < 3; ++c)
        write_plane(dst, in.aovs.channels(Role::Color)[c], denoised[c], roi);
    // The extras' sum stays the denoised beauty.
    if (!extras.empty()) {
        extras.share_rounding(color.mean, denoised);
        extras.pass_through(converged);
        extras.write(dst, roi);
    }
    if (!write_maps(dst, selected, roi))
        return false;
    trace.mark("write");
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
