// The KPCN op (Bako et al. 2017, Fig. 2), top to bottom: per network tile, read the render's
// window, split its light (§4.3) and make the branch's inputs (§5.1) for the branch network
// (§4.2), then undo the transforms and add the branches (eq. 4) into the output — one tile
// per worker thread, each with its own copy of the networks.
#include "mcdn/cnn.h"

#include <cmath>
#include <cstdlib>
#include <mutex>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>

#include "cnn/cnn_steps.h"
#include "cnn/extras_kernels.h"
#include "cnn/worker_pool.h"
#include "core/attributes.h"
#include "ops/color_planes.h"
#include "core/frame_facts.h"
#include "core/op_prepare.h"
#include "core/progress.h"
#include "core/trace.h"
#include "nn/network_regions.h"
#include "nn/with_threads.h"
#include "outliers/outliers.h"
#include "skip/converged_tiles.h"
#include "mcdn/color.h"
#include "mcdn/nfor.h"

namespace mcdn {

namespace {

/// Eq. 4 on `rect` (frame pixels inside the tile's core): colour = (albedo + eps) ·
/// irradiance + exp(log specular) − 1, written into `colour_frame`'s channels `color` except
/// on converged tiles (a tile the network ran on for its neighbours keeps the render); with
/// extras, their shares of the two components too, into `frame` (pass_through_extras
/// restores converged tiles).
void recombine(kpcn::OutputFrame& color_frame, kpcn::OutputFrame& frame, Rect rect,
               const Rect& window, const kpcn::Worker& worker, bool split, const ImageBuf& src,
               const AovSet& aovs, const std::vector<int>& color,
               const std::vector<ExtraPlanes>& extras, const ConvergedTiles& converged)
{
    Plane demod[3];
    if (split)
        kpcn::read_demod(demod, src, aovs, rect);
    kpcn::BranchResult diffuse, specular;
    const bool keep_components = !extras.empty();
    for (int c = 0; c < 3 && keep_components; ++c) {
        specular.component[c] = Plane(rect.width(), rect.height());
        if (split)
            diffuse.component[c] = Plane(rect.width(), rect.height());
    }
    const nn::Tensor& log_spec = worker.log_specular[0];
    const nn::Tensor* irradiance = split ? &worker.irradiance[0] : nullptr;
    for (int y = rect.y0; y < rect.y1; ++y)
        for (int x = rect.x0; x < rect.x1; ++x) {
            const float* ls = log_spec.pixel(y - window.y0, x - window.x0);
            const float* irr = split ? irradiance->pixel(y - window.y0, x - window.x0) : nullptr;
            float* out = color_frame.pixel(x, y);
            const size_t i = size_t(y - rect.y0) * rect.width() + (x - rect.x0);
            const bool render_stays = converged.pixel(x, y);
            for (int c = 0; c < 3; ++c) {
                const float s = std::expm1(ls[c]);
                const float d =
                    split ? (std::max(demod[c].px[i], 0.0f) + kpcn::kAlbedoEpsilon) * irr[c] : 0.0f;
                if (!render_stays)
                    out[color[c]] = sanitize(s + d);
                if (keep_components) {
                    specular.component[c].px[i] = s;
                    if (split)
                        diffuse.component[c].px[i] = d;
                }
            }
        }
    if (!keep_components)
        return;
    for (auto [result, filtered] :
         { std::pair { &diffuse, irradiance }, std::pair { &specular, &log_spec } }) {
        result->filtered = filtered;
        result->window_x0 = window.x0;
        result->window_y0 = window.y0;
    }
    kpcn::write_extras(frame, rect, extras, split ? &diffuse : nullptr, specular);
}

/// The colour of the converged tiles inside `where` is the render's, sanitized (the frame
/// holds the render there: it is sanitized in place).
void pass_through_color(kpcn::OutputFrame& frame, const ImageBuf& dst,
                        const std::vector<int>& color, ROI where, const ConvergedTiles& converged)
{
    if (!converged.any())
        return;
    const ImageSpec& spec = dst.spec();
    for (int y = where.ybegin - spec.y; y < where.yend - spec.y; ++y)
        for (int x = where.xbegin - spec.x; x < where.xend - spec.x; ++x)
            if (converged.pixel(x, y))
                for (int c : color)
                    frame.pixel(x, y)[c] = sanitize(frame.pixel(x, y)[c]);
}

/// CnnOptions::outliers: the heavy-tailed pixels of src by NFOR's rule and thresholds
/// (outliers/outliers.h), taken out of `extras` too (each gives up its share of the excess).
/// Without the colour's variance there is nothing to judge them by: none.
kpcn::DroppedOutliers find_outliers(const ImageBuf& src, const AovSet& aovs,
                                    std::vector<ExtraPlanes>& extras,
                                    const ConvergedTiles& converged, int nthreads)
{
    kpcn::DroppedOutliers dropped;
    if (!aovs.has(Role::ColorVariance))
        return dropped;
    const bool halves = aovs.has(Role::ColorA) && aovs.has(Role::ColorB);
    ColorPlanes color;
    read_color_planes(color, src, aovs, halves);
    // The level floor from the frame's colour (a band's frame's: core/frame_facts.h).
    FrameFacts facts;
    const ColorSums frame = frame_facts(facts, src.spec()) ? facts.color : color_sums(color);
    const NforOptions nfor_options;  // the same thresholds as NFOR's
    const OutlierRule rule =
        outlier_rule(nfor_options.outlier_sigma, nfor_options.outlier_variance_ratio,
                     nfor_options.outlier_level_ratio, frame);
    const OutlierPixels found =
        take_out_outliers(color.mean, color.variance, halves ? color.half_a : nullptr,
                          halves ? color.half_b : nullptr, extras, converged, rule, nthreads);
    for (size_t k = 0; k < found.pixels.size(); ++k) {
        const uint32_t i = found.pixels[k];
        std::array<float, 3> mean, variance, scale;
        for (int c = 0; c < 3; ++c) {
            mean[c] = color.mean[c].px[i];
            variance[c] = color.variance[c].px[i];
            const float rendered = mean[c] + found.excess[k][c];
            scale[c] = rendered > 0.0f ? std::clamp(mean[c] / rendered, 0.0f, 1.0f) : 1.0f;
        }
        dropped.pixels.push_back(i);
        dropped.mean.push_back(mean);
        dropped.variance.push_back(variance);
        dropped.scale.push_back(scale);
    }
    return dropped;
}

// In place, the colour made in a frame of its own (colour channels 0-2) into the output's
// colour channels, inside `where`.
void copy_color(kpcn::OutputFrame& frame, const std::vector<int>& out_color,
                kpcn::OutputFrame& color_frame, const ImageBuf& dst, const ROI& where,
                int first = 0)
{
    for (int y = where.ybegin - dst.spec().y; y < where.yend - dst.spec().y; ++y)
        for (int x = where.xbegin - dst.spec().x; x < where.xend - dst.spec().x; ++x)
            for (int c = 0; c < 3; ++c)
                frame.pixel(x, y)[out_color[c]] = color_frame.pixel(x, y)[first + c];
}

// §4.2 on one tile's window: its inputs (§5.1), then the diffuse and specular networks (the
// specular alone without a split), into the worker's outputs.
bool run_branches(kpcn::Worker& k, const ImageBuf& src, const AovSet& aovs,
                  const kpcn::DepthRange& depth, const std::vector<ExtraPlanes>& extras,
                  const Rect& window, bool split, const kpcn::DroppedOutliers& outliers,
                  std::string& error)
{
    bool ok =
        kpcn::tile_inputs(src, aovs, depth, extras, window, split ? &k.diffuse_inputs : nullptr,
                          k.specular_inputs, error, outliers.empty() ? nullptr : &outliers);
    if (ok && split) {
        ok = k.model.diffuse.run(k.diffuse_inputs.tensors, k.irradiance, error);
        k.model.diffuse.give_buffers(k.model.specular);  // same shapes: no new memory
    }
    ok = ok && k.model.specular.run(k.specular_inputs.tensors, k.log_specular, error);
    if (split)  // back for the next tile (without a split they stay: the one net)
        k.model.specular.give_buffers(k.model.diffuse);
    return ok;
}

// In place, extras that are roles the tiles read around them (Blender's DiffDir, Arnold's
// diffuse: the split) are made in a frame of their own, `made`, written into dst after:
// each extra's channels become the frame's 3e..3e+2, dst's kept in `dst_channels`.
bool set_extras_aside(ImageBuf& made, std::vector<std::vector<int>>& dst_channels,
                      std::vector<ExtraPlanes>& extras, const ImageSpec& dst_spec)
{
    ImageSpec spec = dst_spec;
    spec.nchannels = 3 * int(extras.size());
    spec.channelnames.clear();
    spec.channelformats.clear();
    spec.alpha_channel = spec.z_channel = -1;
    spec.extra_attribs.clear();
    spec.default_channel_names();
    if (!allocate_frame(made, spec, true))
        return false;
    for (size_t e = 0; e < extras.size(); ++e) {
        dst_channels.push_back(extras[e].channels);
        extras[e].channels = { 3 * int(e), 3 * int(e) + 1, 3 * int(e) + 2 };
    }
    return true;
}

/// The workers of one call: taken from earlier calls' when there are (worker_pool.h), handed
/// back at the end.
struct Workers {
    std::vector<std::unique_ptr<kpcn::Worker>> list;
    ~Workers()
    {
        for (auto& w : list)
            kpcn::return_worker(std::move(w));
    }
};

/// What every tile of one call reads.
struct TileRun {
    const ImageBuf& src;
    const AovSet& aovs;
    const kpcn::DepthRange& depth;
    const std::vector<ExtraPlanes>& extras;
    bool split;
    const kpcn::DroppedOutliers& outliers;
    const ConvergedTiles& converged;
    ROI where;
    const ImageBuf& dst;
};

// §4.2 then eq. 4, a tile at a time: one tile per worker, each with its own networks.
bool run_tiles(Workers& worker, const std::string& path, int image_channels,
               const std::vector<nn::Tile>& tiles, const TileRun& run,
               kpcn::OutputFrame& color_frame, const std::vector<int>& color_channels,
               kpcn::OutputFrame& extras_frame, ProgressCounter& progress, int nthreads,
               std::string& error)
{
    return nn::with_threads(nthreads, [&] {
        const int workers = std::min(nn::max_threads(), int(tiles.size()));
        while (int(worker.list.size()) < workers) {
            worker.list.push_back(kpcn::take_worker(path, image_channels, error));
            if (!worker.list.back())
                return false;
        }
        std::mutex failed;
        auto run_tile = [&](int index, int w) {
            kpcn::Worker& k = *worker.list[w];
            const nn::Tile& tile = tiles[index];
            std::string tile_error;
            if (!run_branches(k, run.src, run.aovs, run.depth, run.extras, tile.window, run.split,
                              run.outliers, tile_error)) {
                std::lock_guard<std::mutex> lock(failed);
                if (error.empty())
                    error = "cnn: '" + path + "': " + tile_error;
                return false;
            }
            recombine(color_frame, extras_frame, output_rect(tile.core, run.dst.spec(), run.where),
                      tile.window, k, run.split, run.src, run.aovs, color_channels, run.extras,
                      run.converged);
            return progress.advance(error, failed);
        };
        return nn::for_each_tile(int(tiles.size()), workers, run_tile);
    });
}

bool cnn_in_working_space(ImageBuf& dst, const ImageBuf& src, const CnnOptions& options, ROI roi,
                          int nthreads)
{
    // A SURE probe's result is read for its colour alone (core/attributes.h): then dst is
    // the colour channels, not a copy of every channel of the frame.
    const bool color_only = src.spec().get_int_attribute(kColorOnlyAttribute, 0) == 1;
    // In place, the tiles read the render's colour around them while others write theirs:
    // the colour is made in a frame of its own and then written into dst (the extras' inputs
    // are planes of their own already, read_extras). Else on a copy of the render.
    const bool in_place = &dst == &src;
    if (in_place && (color_only || !float_frame_pixels(src))) {
        const ImageBuf render = src.copy(OIIO::TypeDesc::FLOAT);
        return cnn_in_working_space(dst, render, options, roi, nthreads);
    }
    StageTrace trace("cnn");
    AovSet aovs;
    std::string error;
    if (!prepare_denoiser_output(dst, src, options.aovs, aovs, "cnn", color_only, nthreads))
        return false;
    trace.mark("copy src to dst");
    const std::vector<int> out_color =
        color_only ? std::vector<int> { 0, 1, 2 } : aovs.channels(Role::Color);
    std::vector<ExtraPlanes> extras;
    if (!color_only && denoises_extras(options.denoise_extras, src)
        && !read_extras(extras, dst, aovs, false, error)) {
        dst.errorfmt("cnn: {}", error);
        return false;
    }
    // mcdn/skip.h: nothing to do where every tile is converged (dst is the render).
    const ConvergedTiles converged = converged_tiles_of(src, aovs, options.skip);
    if (converged.all())
        return true;
    // Heavy-tailed samples out of the network's input (CnnOptions::outliers).
    kpcn::DroppedOutliers outliers;
    if (options.outliers == CnnOptions::Outliers::Drop)
        outliers = find_outliers(src, aovs, extras, converged, nthreads);
    trace.mark("outliers");
    kpcn::OutputFrame frame(dst);
    if (!frame.valid()) {
        dst.errorfmt("cnn: the output frame is not in memory");
        return false;
    }
    ImageBuf made_color;  // in place: the colour frame, the render's until a tile writes
    if (in_place)
        made_color = OIIO::ImageBufAlgo::channels(src, 3, out_color);
    kpcn::OutputFrame color_frame(in_place ? made_color : dst);
    const std::vector<int> color_channels = in_place ? std::vector<int> { 0, 1, 2 } : out_color;
    if (!color_frame.valid()) {
        dst.errorfmt("cnn: could not make the colour frame");
        return false;
    }
    ImageBuf made_extras;
    std::vector<std::vector<int>> extra_channels;  // dst's, while the extras are aside
    if (in_place && extras_are_roles(aovs) && !extras.empty()
        && !set_extras_aside(made_extras, extra_channels, extras, dst.spec())) {
        dst.errorfmt("cnn: {}", made_extras.geterror());
        return false;
    }
    kpcn::OutputFrame extras_frame(made_extras.initialized() ? made_extras : dst);
    const std::string path = options.weights.empty() ? default_cnn_weights(&aovs) : options.weights;
    const int image_channels = extras.empty() ? 3 : 3 * (2 + int(extras.size()));
    Workers worker;
    worker.list.push_back(kpcn::take_worker(path, image_channels, error));
    if (!worker.list[0]) {
        dst.errorfmt("{}", error);
        return false;
    }
    const nn::Net& first = worker.list[0]->model.specular;

    // §5.1: the depth range is the one input statistic of the whole frame; everything else
    // (§4.3's split, the 34 input channels, eq. 4) is made per network tile from its window.
    // A band of a larger frame carries the frame's (core/frame_facts.h).
    // A model trained without depth gets none (a zero range: zero depth).
    FrameFacts facts;
    const kpcn::DepthRange depth = !worker.list[0]->model.reads_depth ? kpcn::DepthRange {}
                                   : frame_facts(facts, src.spec()) && facts.has_depth
                                       ? kpcn::DepthRange { facts.depth_lo, facts.depth_span }
                                       : kpcn::depth_range(src, aovs);
    const bool split = kpcn::has_split(aovs);
    const ROI where = output_roi(src, roi);
    std::vector<nn::Tile> tiles;
    if (!network_tiles(tiles, first, converged, options.tile_size, false, src.spec(), where,
                       error)) {
        dst.errorfmt("cnn: {}", error);
        return false;
    }
    trace.mark("networks and depth range");
    ProgressCounter progress(options.progress, "cnn", int(tiles.size()));

    const TileRun run { src, aovs, depth, extras, split, outliers, converged, where, dst };
    const bool ran = run_tiles(worker, path, image_channels, tiles, run, color_frame,
                               color_channels, extras_frame, progress, nthreads, error);
    if (!ran) {
        dst.errorfmt("{}", error);
        return false;
    }
    trace.mark("network tiles (4.2, eq. 4)");
    if (in_place)
        copy_color(frame, out_color, color_frame, dst, where);
    for (size_t e = 0; e < extra_channels.size(); ++e) {
        copy_color(frame, extra_channels[e], extras_frame, dst, where, extras[e].channels[0]);
        extras[e].channels = extra_channels[e];
    }
    // Converged tiles keep the render (sanitized), the extras' too.
    pass_through_color(frame, dst, out_color, where, converged);
    pass_through_extras(dst, where, extras, converged);
    return true;
}

}  // namespace

std::string default_cnn_weights(const AovSet* aovs)
{
    if (aovs && !aovs->has(Role::ColorVariance) && !kpcn::has_split(*aovs)) {
        const std::string can = nn::model_file(kColourAlbedoNormalWeights);
        if (OIIO::Filesystem::exists(can))
            return can;
    }
    return nn::model_file("kpcn.mcdnw");
}

int receptive_radius(const CnnOptions& options)
{
    std::string error;
    const std::string path = options.weights.empty() ? default_cnn_weights() : options.weights;
    std::unique_ptr<kpcn::Worker> worker = kpcn::take_worker(path, 3, error);
    if (!worker)
        return -1;
    const int radius = std::max(worker->model.diffuse.receptive_radius(),
                                worker->model.specular.receptive_radius());
    kpcn::return_worker(std::move(worker));
    // Outliers are decided on the 5×5 neighbourhood of the input (outliers/outliers.h).
    return radius + (options.outliers == CnnOptions::Outliers::Drop ? OutlierRule::radius : 0);
}

bool cnn(ImageBuf& dst, const ImageBuf& src, const CnnOptions& options, ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "cnn"))
        return false;
    if (!run_in_working_space(dst, src, options.aovs, "cnn", [&](ImageBuf& d, const ImageBuf& s) {
            return cnn_in_working_space(d, s, options, roi, nthreads);
        }))
        return false;
    dst.specmod().attribute(kDenoiserAttribute, "cnn");
    return true;
}

ImageBuf cnn(const ImageBuf& src, const CnnOptions& options, ROI roi, int nthreads)
{
    ImageBuf dst;
    cnn(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
