// NFOR's two passes of regressions and the selection between them (passes.h): §5.2's
// first pass (two-buffer, or one-buffer with a SURE probe), §5.3's MSE estimates and
// selection, §5.4's second pass.
#include "nfor/passes.h"

#include <algorithm>
#include <cmath>

#include "core/attributes.h"
#include "core/random.h"
#include "mcdn/color.h"
#include "nfor/mse_estimate.h"
#include "nfor/regression.h"
#include "nl_means/nl_means.h"
#include "skip/worse_tiles.h"

namespace mcdn {

namespace {

constexpr uint64_t kNforProbeSeed = 0x6e666f72;  // "nfor": the one-buffer SURE probe

}  // namespace

namespace {

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

}  // namespace

namespace {

/// The candidates of one regression into `fits` (one per bandwidth).
void take_candidates(std::vector<Plane> fits[2], std::vector<std::vector<Plane>> result)
{
    fits[0] = std::move(result[0]);
    fits[1] = std::move(result[1]);
}

}  // namespace

namespace {

/// The features' halves after §5.2, their last use.
void free_feature_halves(std::vector<FeaturePlanes>& features)
{
    for (FeaturePlanes& f : features) {
        f.half_a = Plane();
        f.half_b = Plane();
    }
}

}  // namespace

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
    const Plane zero_offset =
        neighbours.empty() ? Plane() : Plane(color.mean[0].width, color.mean[0].height);
    add_neighbour_frames(first_a, neighbours, Face::HalfA, Face::HalfB, Face::HalfB, zero_offset);
    add_neighbour_frames(first_b, neighbours, Face::HalfB, Face::HalfA, Face::HalfA, zero_offset);
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

/// Without half buffers (a renderer's colour and its variance, as Arnold and RenderMan
/// write them), §5.2 fits the render itself with its own weights and the mean features for
/// both candidates, and once more probed by eps b, b = sqrt(Var) n (n standard normal, from
/// the pixel's index: the same for any thread count), so that §5.3 can pick by SURE
/// (PD §2.3) instead of the two-buffer estimate. fit_b stays empty.
FirstPass first_pass_one_buffer(const ColorPlanes& color, std::vector<FeaturePlanes>& features,
                                const std::vector<NeighbourFrame>& neighbours, ExtraAovs& extras,
                                const NforOptions& options, const ConvergedTiles& converged,
                                int nthreads, std::vector<Plane> mse[2],
                                const ProbeIndex& probe_index)
{
    RegressionInputs first = first_pass_settings(options, converged);
    for (const FeaturePlanes& f : features)
        first.features.push_back(&f.mean);
    // §8: the neighbouring frames' windows join every fit, unprobed (SURE's divergence is
    // this frame's).
    const Plane zero_offset =
        neighbours.empty() ? Plane() : Plane(color.mean[0].width, color.mean[0].height);
    add_neighbour_frames(first, neighbours, Face::Mean, Face::Mean, Face::Mean, zero_offset);
    const double eps = relative_probe_step(probe_index.color, 1e-3);
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
    std::vector<Plane> filtered_mse =
        nl_means(noisy, map_guide, map_variance, map_params, nthreads, &converged);
    // The safety net's map (skip/worse_tiles.h): the one attached to src (a probe of sure's)
    // when it has one of the frame's size; else decided on the estimates as they were,
    // before the map filter spread a garbage pixel's estimate over its window, so those
    // are kept until the blend.
    Selected out;
    const int w = color.mean[0].width, h = color.mean[0].height;
    const bool decide =
        options.fallback && !attached_tiles(out.fallback, src, kDenoiserTilesAttribute, w, h);
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
        out.fallback =
            tiles_worse_than_render(mse[0].data(), color.variance, out.combined, converged);
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

}  // namespace mcdn
