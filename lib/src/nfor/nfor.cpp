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
#include "nfor/passes.h"
#include "outliers/outliers.h"
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
                     "patch {}, k {} and {})",
                     o.window_radius, o.patch_radius, o.candidate_k[0], o.candidate_k[1]);
    return ok;
}

/// The options' outlier rule (outliers/outliers.h).
OutlierRule outlier_rule(const NforOptions& o, const ColorSums& frame)
{
    return outlier_rule(o.outlier_sigma, o.outlier_variance_ratio, o.outlier_level_ratio, frame);
}

/// What the op reads from src before anything is written (dst may be src).
struct NforInputs {
    AovSet aovs;
    bool halves = false;       // else the one-buffer path: the render and its variance only
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
        || !find_feature_channels(feature_channels, in.aovs, src.spec(), options.extra_features, op,
                                  error)) {
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
        dst.errorfmt(
            "nfor needs two half buffers or the colour's variance, and {} has "
            "neither: render two half buffers (each the mean of half the samples: "
            "-i:as=halfA, -i:as=halfB) or the variance (the renderer's variance "
            "AOV, or -i:as=variance FILE), or use a stage that needs none "
            "(--denoise, --cnn); roles color_a, color_b, color_variance (preset '{}')",
            channel_source(src.spec(), src.spec().channel_name(in.aovs.channels(Role::Color)[0])),
            in.aovs.preset());
        return false;
    }
    // Cross-frame, the frame offset is one more feature.
    const int max_features = kMaxRegressionFeatures - (options.cross_frame() ? 1 : 0);
    if (int(feature_channels.size()) > max_features) {
        dst.errorfmt("nfor: {} feature channels, at most {} are supported{}; drop extra "
                     "features",
                     feature_channels.size(), max_features,
                     options.cross_frame() ? " cross-frame" : "");
        return false;
    }
    if (options.cross_frame() && !in.aovs.has(Role::Motion)) {
        dst.errorfmt(
            "nfor: cross-frame needs motion vectors and {} has none: render the "
            "Vector pass (Blender) or name them (--aov motion=X,Y,Z,W)",
            channel_source(src.spec(), src.spec().channel_name(in.aovs.channels(Role::Color)[0])));
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

/// The nfor.mse.*, nfor.selection.* and nfor.fallback channels, when asked for.
bool write_maps(ImageBuf& dst, Selected& selected, const NforOptions& options, const Plane& like,
                ROI roi)
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
        write_plane(dst, new_index[n], tile_flags(selected.fallback, like.width, like.height), roi);
    return true;
}

/// §8's neighbouring frames, read as this one (its roles, features and halves) and aligned
/// to it; an error on dst.
bool read_neighbours(std::vector<NeighbourFrame>& neighbours, ImageBuf& dst, const ImageBuf& src,
                     const NforInputs& in, const NforOptions& options, const ColorSums& frame,
                     int nthreads)
{
    NeighbourReading reading;
    reading.spec = &options.aovs;
    reading.aovs = &in.aovs;
    reading.features = &in.feature_channels;
    reading.halves = in.halves;
    reading.prefilter = options.prefilter_features;
    reading.prefilter_options = options.prefilter;
    reading.outliers = options.outliers != NforOptions::Outliers::Off;
    reading.outlier_rule = outlier_rule(options, frame);
    std::string error;
    if (!read_neighbour_frames(neighbours, src, options.previous_frames, options.next_frames,
                               reading, nthreads, error)) {
        dst.errorfmt("nfor: {}", error);
        return false;
    }
    return true;
}

/// The render where the result is not NFOR's: a non-finite value (the regression already
/// falls back per pixel), converged tiles and the safety net's; the extras' sum stays the
/// denoised beauty, before and after the outliers' excess (put back when `keep_outliers`).
void render_where_not_denoised(std::vector<Plane>& denoised, ExtraAovs& extras,
                               const ColorPlanes& color, const ConvergedTiles& converged,
                               const ConvergedTiles& fallback, const OutlierPixels& outliers,
                               bool keep_outliers)
{
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < denoised[c].size(); ++i)
            if (!std::isfinite(denoised[c].px[i]))
                denoised[c].px[i] = color.mean[c].px[i];
    for (int c = 0; c < 3; ++c) {
        pass_through_converged(denoised[c], color.mean[c], converged);
        pass_through_converged(denoised[c], color.mean[c], fallback);
    }
    if (!extras.empty()) {
        extras.share_rounding(color.mean, denoised);
        if (keep_outliers)
            extras.put_back_outliers(outliers);
        extras.pass_through(converged);
        extras.pass_through(fallback);
    }
    if (keep_outliers)
        put_back_outliers(outliers, denoised.data());
}

/// The result into dst (a copy of src) inside roi: the colour, the extras, the maps asked
/// for, the safety net's tiles and count, and with features-out the prefiltered features.
bool write_result(ImageBuf& dst, const NforInputs& in, const std::vector<Plane>& denoised,
                  ExtraAovs& extras, Selected& selected, const NforOptions& options,
                  bool prefiltered, ROI roi)
{
    for (int c = 0; c < 3; ++c)
        write_plane(dst, in.aovs.channels(Role::Color)[c], denoised[c], roi);
    if (!extras.empty())
        extras.write(dst, roi);
    if (!write_maps(dst, selected, options, in.color.mean[0], roi))
        return false;
    if (selected.fallback.any()) {
        dst.specmod().attribute(kDenoiserTilesAttribute, encode_converged_tiles(selected.fallback));
        dst.specmod().attribute(kNforFallbackCountAttribute, selected.fallback.count());
    } else {
        dst.specmod().erase_attribute(kDenoiserTilesAttribute);
        dst.specmod().erase_attribute(kNforFallbackCountAttribute);
    }
    // features-out: the means it prefiltered (§5.1) over their channels.
    if (options.features_out && !prefiltered && options.prefilter_features)
        for (size_t i = 0; i < in.features.size(); ++i)
            write_plane(dst, in.feature_channels[i].mean, in.features[i].mean, roi);
    return true;
}

bool nfor_in_working_space(ImageBuf& dst, const ImageBuf& src, const NforOptions& options, ROI roi,
                           int nthreads, ProgressCounter& progress)
{
    if (!check_options(dst, options))
        return false;
    StageTrace trace("nfor");
    NforInputs in;
    if (!read_inputs(in, dst, src, options))
        return false;
    ColorPlanes& color = in.color;
    // mcdn/skip.h: converged tiles pass through every stage below; constant features go.
    const ConvergedTiles converged =
        converged_tiles_of(src, color.mean, color.variance, options.skip);
    // The frame's colour (of a band's frame: core/frame_facts.h), before anything changes it.
    FrameFacts facts;
    ProbeIndex probe_index;
    if (frame_facts(facts, src.spec())) {
        probe_index.facts = &facts;
        probe_index.first = uint64_t(src.spec().y - facts.ybegin) * uint64_t(src.spec().width);
    }
    probe_index.color = probe_index.facts ? facts.color : color_sums(color);
    // Heavy-tailed samples are kept out of the regressions and put back after them
    // (outliers/outliers.h).
    OutlierPixels outliers;
    if (options.outliers != NforOptions::Outliers::Off)
        outliers = take_out_outliers(color.mean, color.variance, in.halves ? color.half_a : nullptr,
                                     in.halves ? color.half_b : nullptr, in.extras, converged,
                                     outlier_rule(options, probe_index.color), nthreads);
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
        if (!read_neighbours(neighbours, dst, src, in, options, probe_index.color, nthreads))
            return false;
        trace.mark("neighbouring frames (8)");
    }
    if (!progress.advance()) {
        dst.errorfmt("{}", progress.error());
        return false;
    }
    std::vector<Plane> mse[2];
    FirstPass pass =
        in.halves ? first_pass(color, in.features, neighbours, extras, options, converged, nthreads)
                  : first_pass_one_buffer(color, in.features, neighbours, extras, options,
                                          converged, nthreads, mse, probe_index);
    neighbours.clear();
    if (in.halves)
        two_buffer_mse(mse, color, pass);
    trace.mark("first pass regressions (5.2)");
    if (!progress.advance()) {
        dst.errorfmt("{}", progress.error());
        return false;
    }
    Selected selected =
        select_bandwidths(src, color, mse, pass, extras, options, converged, nthreads);
    trace.mark("MSE + selection maps (5.3)");
    if (!progress.advance()) {
        dst.errorfmt("{}", progress.error());
        return false;
    }
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
    if (!progress.advance()) {
        dst.errorfmt("{}", progress.error());
        return false;
    }

    render_where_not_denoised(denoised, extras, color, converged, selected.fallback, outliers,
                              options.outliers == NforOptions::Outliers::Keep);

    // dst (a copy of src) is made only now, when the working planes are gone; everything was
    // read from src before (dst may be src).
    if (!prepare_op(dst, src, options.aovs, in.aovs, "nfor", nthreads))
        return false;
    trace.mark("copy src to dst");
    if (!write_result(dst, in, denoised, extras, selected, options, prefiltered,
                      output_roi(dst, roi)))
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
    int prefilter =
        prefiltered || !o.prefilter_features
            ? 0
            : p.window_radius + p.patch_radius + p.second_window_radius + p.second_patch_radius;
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
    const int64_t band_pixels =
        is_frame_band(src.spec()) || options.cross_frame() ? 0 : options.band_pixels;
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
