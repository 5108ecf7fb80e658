// mcdn::nfor, reading like the paper: prefiltered features (§5.1), first pass of
// cross-filtered regressions for two bandwidths (§5.2), MSE estimate and bandwidth selection
// (§5.3), second pass on the averaged halves (§5.4).
//
// Renderers that write a variance but no half buffers (Arnold, RenderMan) take the
// one-buffer path: §5.2 fits the render with its own weights, §5.3 picks the bandwidth by
// SURE (PD §2.3) on a probed second fit, and there is no §5.4 (its variance is the halves'
// difference).
#include "mcdn/nfor.h"

#include <algorithm>
#include <cmath>

#include <OpenImageIO/imagebufalgo.h>

#include "core/channels.h"
#include "skip/constant_features.h"
#include "skip/converged_tiles.h"
#include "core/attributes.h"
#include "core/extra_aovs.h"
#include "core/feature_channels.h"
#include "core/frame_facts.h"
#include "nl_means/nl_means.h"
#include "ops/bands.h"
#include "core/op_prepare.h"
#include "core/progress.h"
#include "core/random.h"
#include "core/trace.h"
#include "mcdn/color.h"
#include "nfor/extras_regression.h"
#include "skip/worse_tiles.h"
#include "nfor/mse_estimate.h"
#include "nfor/neighbour_frames.h"
#include "outliers/outliers.h"
#include "nfor/regression.h"
#include "prefilter/feature_prefilter.h"

namespace mcdn {
namespace {

constexpr uint64_t kNforProbeSeed = 0x6e666f72;  // "nfor": the one-buffer SURE probe

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

/// The options' outlier rule (outliers/outliers.h).
OutlierRule outlier_rule(const NforOptions& o, const ColourSums& frame)
{
    return outlier_rule(o.outlier_sigma, o.outlier_variance_ratio, o.outlier_level_ratio, frame);
}

/// What the op reads from src before anything is written (dst may be src).
struct NforInputs {
    AovSet aovs;
    bool halves = false;  // else the one-buffer path: the render and its variance only
    bool prefiltered = false;  // the prefilter op ran already (mcdn:prefiltered)
    bool means_later = false;  // the features' means are read after §5.2 (read_inputs)
    ColorPlanes color;
    std::vector<FeaturePlanes> features;
    std::vector<FeatureChannel> feature_channels;  // where each of `features` came from
    std::vector<ExtraPlanes> extras;
};

bool read_inputs(NforInputs& in, ImageBuf& dst, const ImageBuf& src, const NforOptions& options)
{
    const char* op = "nfor";
    std::string error;
    std::vector<FeatureChannel>& feature_channels = in.feature_channels;
    if (!resolve_aovs(in.aovs, options.aovs, src.spec(), error)
        || !in.aovs.require({ Role::Color }, src.spec(), error)
        || !find_feature_channels(feature_channels, in.aovs, src.spec(), options.extra_features,
                                  op, error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    // Two half buffers (§5.2's cross filtering), else the render's variance (the one-buffer
    // path); with neither there is nothing to estimate the error from.
    in.halves = options.use_halves && in.aovs.has(Role::ColorA) && in.aovs.has(Role::ColorB);
    if (!options.use_halves)  // as if the renderer wrote none: the features' go too
        for (FeatureChannel& f : feature_channels)
            f.half_a = f.half_b = -1;
    if (!in.halves && !in.aovs.has(Role::ColorVariance)) {
        dst.errorfmt("nfor needs two half buffers or the colour's variance, and {} has "
                     "neither: render two half buffers (each the mean of half the samples: "
                     "-i:as=halfA, -i:as=halfB) or the variance (the renderer's variance "
                     "AOV, or -i:as=variance FILE), or use a stage that needs none "
                     "(--denoise, --cnn); roles color_a, color_b, color_variance (preset '{}')",
                     channel_source(src.spec(), src.spec().channel_name(
                                                    in.aovs.channels(Role::Color)[0])),
                     in.aovs.preset());
        return false;
    }
    // Cross-frame, the frame offset is one more feature.
    const int max_features = kMaxRegressionFeatures - (options.cross_frame() ? 1 : 0);
    if (int(feature_channels.size()) > max_features) {
        dst.errorfmt("nfor: {} feature channels, at most {} are supported{}; drop extra "
                     "features", feature_channels.size(), max_features,
                     options.cross_frame() ? " cross-frame" : "");
        return false;
    }
    if (options.cross_frame() && !in.aovs.has(Role::Motion)) {
        dst.errorfmt("nfor: cross-frame needs motion vectors and {} has none: render the "
                     "Vector pass (Blender) or name them (--aov motion=X,Y,Z,W)",
                     channel_source(src.spec(), src.spec().channel_name(
                                                    in.aovs.channels(Role::Color)[0])));
        return false;
    }
    for (Role role : { Role::Color, Role::ColorA, Role::ColorB, Role::ColorVariance })
        if (in.aovs.has(role) && in.aovs.channels(role).size() != 3) {
            dst.errorfmt("nfor: role {} needs 3 channels, got {}", role_name(role),
                         in.aovs.channels(role).size());
            return false;
        }
    read_color_planes(in.color, src, in.aovs, in.halves);
    // The features' variances serve §5.1 alone, whose result replaces their means. With
    // half buffers §5.2 fits with the features' halves, so their means are read only for
    // §5.4 (read_feature_means): a plane per feature less at the peaks of §5.2 and §5.3.
    in.prefiltered = src.spec().get_int_attribute("mcdn:prefiltered", 0) == 1;
    const bool prefilters = !in.prefiltered && options.prefilter_features;
    in.means_later = in.halves && !options.cross_frame();
    FeatureFaces faces;
    faces.mean = !in.means_later && !prefilters;
    faces.variance = prefilters;
    in.features = read_features(src, feature_channels, faces);
    if (!faces.mean)
        read_means_of_constant_halves(in.features, src, feature_channels);
    if (denoises_extras(options.denoise_extras, src)
        && !read_extras(in.extras, src, in.aovs, in.halves, error)) {
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

/// The first pass's regression settings (§5.2, both candidate bandwidths); the caller says
/// what is fitted and guided by what.
RegressionInputs first_pass_settings(const NforOptions& options, const ConvergedTiles& converged)
{
    RegressionInputs in;
    in.window_radius = options.window_radius;
    in.patch_radius = options.patch_radius;
    in.bandwidths = { options.candidate_k[0], options.candidate_k[1] };
    in.variance_scale = options.variance_scale;
    in.skip_tiles = &converged;
    return in;
}

/// The candidates of one regression into `fits` (one per bandwidth).
void take_candidates(std::vector<Plane> fits[2], std::vector<std::vector<Plane>> result)
{
    fits[0] = std::move(result[0]);
    fits[1] = std::move(result[1]);
}

/// The features' halves after §5.2, their last use.
void free_feature_halves(std::vector<FeaturePlanes>& features)
{
    for (FeaturePlanes& f : features) {
        f.half_a = Plane();
        f.half_b = Plane();
    }
}

/// §5.2: half A fitted with the features and colour weights of half B, and vice versa, for
/// each candidate bandwidth. The features' halves are not needed after it.
FirstPass first_pass(const ColorPlanes& color, std::vector<FeaturePlanes>& features,
                     const std::vector<NeighbourFrame>& neighbours, ExtraAovs& extras,
                     const NforOptions& options, const ConvergedTiles& converged, int nthreads)
{
    RegressionInputs first_a = first_pass_settings(options, converged), first_b = first_a;
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
    // §8: the neighbouring frames' windows join every fit.
    const Plane zero_offset = neighbours.empty() ? Plane()
                                                 : Plane(color.mean[0].width, color.mean[0].height);
    add_neighbour_frames(first_a, neighbours, Face::HalfA, Face::HalfB,
                         Face::HalfB, zero_offset);
    add_neighbour_frames(first_b, neighbours, Face::HalfB, Face::HalfA,
                         Face::HalfA, zero_offset);
    FirstPass pass;
    take_candidates(pass.fit_a, collaborative_regression(first_a, nthreads));
    take_candidates(pass.fit_b, collaborative_regression(first_b, nthreads));
    extras.first_pass(first_a, first_b, nthreads);
    free_feature_halves(features);
    return pass;
}

/// §5.3 by the two-buffer estimate: each candidate's MSE from the other half. The colour's
/// halves are not needed after it.
void two_buffer_mse(std::vector<Plane> mse[2], ColorPlanes& color, const FirstPass& pass)
{
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
}

/// The probe step of the one-buffer SURE, relative to the render's scale as in the sure op
/// (SureOptions::epsilon_relative): eps sqrt(Var) moves a pixel of
/// mean standard deviation by 1e-3 of the mean |x|.
/// Where the probes' index space starts: one-buffer NFOR draws b of a pixel by its index in
/// the frame (of a band's frame, core/frame_facts.h), and takes the frame's probe step.
struct ProbeIndex {
    const FrameFacts* facts = nullptr;
    uint64_t first = 0;
    ColourSums colour;  // the frame's (facts->colour), else the planes' as read
};

/// Without half buffers (a renderer's colour and its variance, as Arnold and RenderMan
/// write them), §5.2 fits the render itself with its own weights and the mean features for
/// both candidates, and once more probed by eps b, b = sqrt(Var) n (n standard normal, from
/// the pixel's index: the same for any thread count), so that §5.3 can pick by SURE
/// (PD §2.3) instead of the two-buffer estimate. fit_b stays empty.
FirstPass first_pass_one_buffer(const ColorPlanes& color, std::vector<FeaturePlanes>& features,
                                const std::vector<NeighbourFrame>& neighbours,
                                ExtraAovs& extras, const NforOptions& options,
                                const ConvergedTiles& converged, int nthreads,
                                std::vector<Plane> mse[2], const ProbeIndex& probe_index)
{
    RegressionInputs first = first_pass_settings(options, converged);
    for (const FeaturePlanes& f : features)
        first.features.push_back(&f.mean);
    // §8: the neighbouring frames' windows join every fit, unprobed (SURE's divergence is
    // this frame's).
    const Plane zero_offset = neighbours.empty() ? Plane()
                                                 : Plane(color.mean[0].width, color.mean[0].height);
    add_neighbour_frames(first, neighbours, Face::Mean, Face::Mean,
                         Face::Mean, zero_offset);
    const double eps = relative_probe_step(probe_index.colour, 1e-3);
    Plane probe[3], probed[3];
    for (int c = 0; c < 3; ++c) {
        first.image[c] = first.guide[c] = &color.mean[c];
        first.variance[c] = &color.variance[c];
        probe[c] = Plane(color.mean[c].width, color.mean[c].height);
        probed[c] = probe[c];
        for (size_t i = 0; i < probe[c].size(); ++i) {
            probe[c].px[i] = std::sqrt(color.variance[c].px[i])
                             * standard_normal(kNforProbeSeed, uint64_t(c), probe_index.first + i);
            probed[c].px[i] = float(color.mean[c].px[i] + eps * probe[c].px[i]);
        }
    }
    RegressionInputs probed_inputs = first;
    for (int c = 0; c < 3; ++c)
        probed_inputs.image[c] = probed_inputs.guide[c] = &probed[c];
    FirstPass pass;
    take_candidates(pass.fit_a, collaborative_regression(first, nthreads));
    const std::vector<std::vector<Plane>> fits = collaborative_regression(probed_inputs, nthreads);
    const Plane* render[3] = { &color.mean[0], &color.mean[1], &color.mean[2] };
    const Plane* variance[3] = { &color.variance[0], &color.variance[1], &color.variance[2] };
    for (int j = 0; j < 2; ++j)
        mse[j] = sure_mse(render, variance, probe, eps, pass.fit_a[j], fits[j]);
    extras.first_pass_one_buffer(first, nthreads);
    free_feature_halves(features);
    return pass;
}

/// §5.3's result: the candidates blended per pixel, which is what §5.4 filters, and the
/// blended MSE estimate and selection map when asked for.
struct Selected {
    Plane combined[3], combined_variance[3];
    std::vector<Plane> mse, selection;
    ConvergedTiles fallback;  // the safety net's tiles (skip/worse_tiles.h)
};

/// §5.3: each candidate's MSE estimate NL-means filtered on the mean colour; the lower one
/// picked per pixel; that selection map filtered the same way and the candidates blended
/// with it (both halves' fits, or the render's alone on the one-buffer path). Consumes the
/// MSE estimates, the fits and the colour's variance.
Selected select_bandwidths(const ImageBuf& src, ColorPlanes& color, std::vector<Plane> mse[2],
                           FirstPass& pass, ExtraAovs& extras, const NforOptions& options,
                           const ConvergedTiles& converged, int nthreads)
{
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
    // The safety net's map (skip/worse_tiles.h): the one attached to src (a probe of sure's)
    // when it has one of the frame's size; else decided on the estimates as they were,
    // before the map filter spread a garbage pixel's estimate over its window, so those
    // are kept until the blend.
    Selected out;
    const int w = color.mean[0].width, h = color.mean[0].height;
    const bool decide = options.fallback
                        && !attached_tiles(out.fallback, src, kDenoiserTilesAttribute, w, h);
    if (!decide)
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
    out.selection = nl_means(noisy, map_guide, map_variance, map_params, nthreads, &converged);
    selection_noisy.clear();

    const std::vector<Plane>& selection = out.selection;
    for (int c = 0; c < 3; ++c) {
        out.combined[c] = Plane(color.mean[c].width, color.mean[c].height);
        out.combined_variance[c] = out.combined[c];
        for (size_t i = 0; i < out.combined[c].size(); ++i) {
            float s = selection[c].px[i];
            float a = blend_candidates(pass.fit_a, c, i, s);
            float b = pass.fit_b[0].empty() ? a : blend_candidates(pass.fit_b, c, i, s);
            // §5.4 filters the average of the halves, whose variance the halves' squared
            // difference estimates.
            out.combined[c].px[i] = 0.5f * (a + b);
            out.combined_variance[c].px[i] = sanitize_variance(0.25f * (b - a) * (b - a));
            mse0[c].px[i] = mse0[c].px[i] + s * (mse1[c].px[i] - mse0[c].px[i]);
            if (decide)
                mse[0][c].px[i] += s * (mse[1][c].px[i] - mse[0][c].px[i]);
        }
    }
    if (decide) {
        out.fallback = tiles_worse_than_render(mse[0].data(), color.variance, out.combined,
                                               converged);
        for (int j = 0; j < 2; ++j)
            mse[j].clear();
    }
    for (int c = 0; c < 3; ++c)
        color.variance[c] = Plane();
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
    if (!options.features_out)
        features.clear();
    return denoised;
}

/// The nfor.mse.*, nfor.selection.* and nfor.fallback channels, when asked for.
bool write_maps(ImageBuf& dst, Selected& selected, const NforOptions& options,
                const Plane& like, ROI roi)
{
    std::vector<std::string> names;
    if (!selected.mse.empty())
        for (const char* n : { "nfor.mse.R", "nfor.mse.G", "nfor.mse.B" })
            names.push_back(n);
    if (!selected.selection.empty())
        for (const char* n : { "nfor.selection.R", "nfor.selection.G", "nfor.selection.B" })
            names.push_back(n);
    if (options.output_fallback)
        names.push_back("nfor.fallback");
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
    if (options.output_fallback)
        write_plane(dst, new_index[n], tile_flags(selected.fallback, like.width, like.height),
                    roi);
    return true;
}

bool nfor_in_working_space(ImageBuf& dst, const ImageBuf& src, const NforOptions& options,
                           ROI roi, int nthreads, ProgressCounter& progress)
{
    if (!check_options(dst, options))
        return false;
    StageTrace trace("nfor");
    NforInputs in;
    if (!read_inputs(in, dst, src, options))
        return false;
    ColorPlanes& color = in.color;
    // mcdn/skip.h: converged tiles pass through every stage below; constant features go.
    const ConvergedTiles converged = converged_tiles_of(src, color.mean, color.variance,
                                                        options.skip);
    // The frame's colour (of a band's frame: core/frame_facts.h), before anything changes it.
    FrameFacts facts;
    ProbeIndex probe_index;
    if (frame_facts(facts, src.spec())) {
        probe_index.facts = &facts;
        probe_index.first = uint64_t(src.spec().y - facts.ybegin) * uint64_t(src.spec().width);
    }
    probe_index.colour = probe_index.facts ? facts.colour : colour_sums(color);
    // Heavy-tailed samples are kept out of the regressions and put back after them
    // (outliers/outliers.h).
    OutlierPixels outliers;
    if (options.outliers != NforOptions::Outliers::Off)
        outliers = take_out_outliers(color.mean, color.variance,
                                     in.halves ? color.half_a : nullptr,
                                     in.halves ? color.half_b : nullptr, in.extras, converged,
                                     outlier_rule(options, probe_index.colour), nthreads);
    // Extra AOVs go through the beauty's filters stage by stage (nfor/extras_regression.h).
    ExtraAovs extras(std::move(in.extras));
    if (options.skip.enabled)
        drop_constant_features(in.features, in.feature_channels, src.spec());
    trace.mark("read planes");

    const bool prefiltered = in.prefiltered;
    prefilter_features(in.features, options, prefiltered, converged, nthreads);
    trace.mark("prefilter (5.1)");
    // §8: the neighbouring frames, read as this one and aligned to it.
    std::vector<NeighbourFrame> neighbours;
    if (options.cross_frame()) {
        NeighbourReading reading;
        reading.spec = &options.aovs;
        reading.aovs = &in.aovs;
        reading.features = &in.feature_channels;
        reading.halves = in.halves;
        reading.prefilter = options.prefilter_features;
        reading.prefilter_options = options.prefilter;
        reading.outliers = options.outliers != NforOptions::Outliers::Off;
        reading.outlier_rule = outlier_rule(options, probe_index.colour);
        std::string error;
        if (!read_neighbour_frames(neighbours, src, options.previous_frames,
                                   options.next_frames, reading, nthreads, error)) {
            dst.errorfmt("nfor: {}", error);
            return false;
        }
        trace.mark("neighbouring frames (8)");
    }
    progress.advance();
    std::vector<Plane> mse[2];
    FirstPass pass = in.halves ? first_pass(color, in.features, neighbours, extras, options,
                                            converged, nthreads)
                               : first_pass_one_buffer(color, in.features, neighbours, extras,
                                                       options, converged, nthreads, mse,
                                                       probe_index);
    neighbours.clear();
    if (in.halves)
        two_buffer_mse(mse, color, pass);
    trace.mark("first pass regressions (5.2)");
    progress.advance();
    Selected selected = select_bandwidths(src, color, mse, pass, extras, options, converged,
                                          nthreads);
    trace.mark("MSE + selection maps (5.3)");
    progress.advance();
    std::vector<Plane> denoised;
    if (in.halves) {
        if (in.means_later)  // src is still as read: nothing is written before the end
            read_feature_means(in.features, src, in.feature_channels);
        denoised = second_pass(selected, in.features, extras, options, converged, nthreads);
    } else {  // §5.4 filters the halves' average with their difference as its variance
        for (int c = 0; c < 3; ++c)
            denoised.push_back(std::move(selected.combined[c]));
        extras.blend_is_result();
        if (!options.features_out)
            in.features.clear();
    }
    trace.mark("second pass (5.4)");
    progress.advance();

    // Nothing non-finite leaves the op (the regression already falls back per pixel).
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < denoised[c].size(); ++i)
            if (!std::isfinite(denoised[c].px[i]))
                denoised[c].px[i] = color.mean[c].px[i];
    for (int c = 0; c < 3; ++c) {
        pass_through_converged(denoised[c], color.mean[c], converged);
        pass_through_converged(denoised[c], color.mean[c], selected.fallback);
    }
    // The extras' sum stays the denoised beauty, before and after the outliers' excess.
    const bool keep_outliers = options.outliers == NforOptions::Outliers::Keep;
    if (!extras.empty()) {
        extras.share_rounding(color.mean, denoised);
        if (keep_outliers)
            extras.put_back_outliers(outliers);
        extras.pass_through(converged);
        extras.pass_through(selected.fallback);
    }
    if (keep_outliers)
        put_back_outliers(outliers, denoised.data());

    // dst (a copy of src) is made only now, when the working planes are gone; everything was
    // read from src before (dst may be src).
    if (!prepare_op(dst, src, options.aovs, in.aovs, "nfor", nthreads))
        return false;
    trace.mark("copy src to dst");
    roi = output_roi(dst, roi);
    for (int c = 0; c < 3; ++c)
        write_plane(dst, in.aovs.channels(Role::Color)[c], denoised[c], roi);
    if (!extras.empty())
        extras.write(dst, roi);
    if (!write_maps(dst, selected, options, color.mean[0], roi))
        return false;
    if (selected.fallback.any()) {
        dst.specmod().attribute(kDenoiserTilesAttribute,
                                encode_converged_tiles(selected.fallback));
        dst.specmod().attribute(kNforFallbackCountAttribute, selected.fallback.count());
    } else {
        dst.specmod().erase_attribute(kDenoiserTilesAttribute);
        dst.specmod().erase_attribute(kNforFallbackCountAttribute);
    }
    // features-out: the means it prefiltered (§5.1) over their channels.
    if (options.features_out && !prefiltered && options.prefilter_features)
        for (size_t i = 0; i < in.features.size(); ++i)
            write_plane(dst, in.feature_channels[i].mean, in.features[i].mean, roi);
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
    // Outliers are decided on the 5×5 neighbourhood of the input (outliers/outliers.h).
    const int outliers = o.outliers != NforOptions::Outliers::Off ? OutlierRule::radius : 0;
    return outliers + prefilter + 2 * o.window_radius + o.patch_radius
           + 2 * (o.map_window_radius + o.map_patch_radius) + 2 * o.second_window_radius
           + o.second_patch_radius;
}

bool nfor(ImageBuf& dst, const ImageBuf& src, const NforOptions& options, ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "nfor"))
        return false;
    bool prefiltered = src.spec().get_int_attribute("mcdn:prefiltered", 0) == 1;
    const int radius = receptive_radius(options, prefiltered);
    // A chain's band (core/frame_facts.h) runs whole.
    // Cross-frame, the neighbours are aligned to the whole frame.
    const int64_t band_pixels = is_frame_band(src.spec()) || options.cross_frame()
                                    ? 0
                                    : options.band_pixels;
    // Four steps a band: §5.1, §5.2, §5.3, §5.4.
    ProgressCounter progress(options.progress, "nfor",
                             4 * band_count(src.roi(), radius, band_pixels));
    if (!run_local_op(dst, src, options.aovs, "nfor", radius, band_pixels,
                      [&](ImageBuf& d, const ImageBuf& s) {
                          return nfor_in_working_space(d, s, options, roi, nthreads, progress);
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
