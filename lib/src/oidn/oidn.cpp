// The oidn op (mcdn/oidn.h) top to bottom: find the user's weights for the inputs there are,
// read them (oidn_steps.h read_tza) and build OIDN's UNet on our engine, the frame's exposure,
// then per pass (the beauty, each light AOV) the planes it reads and per network tile: the
// transformed inputs, the network with every thread, the inverse transform into the output.
#include "mcdn/oidn.h"

#include <algorithm>
#include <array>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/extra_aovs.h"
#include "core/frame_facts.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "core/progress.h"
#include "core/trace.h"
#include "mcdn/color.h"
#include "mcdn/version.h"
#include "nn/network_regions.h"
#include "nn/parallel.h"
#include "nn/with_threads.h"
#include "ops/color_planes.h"
#include "outliers/outliers.h"
#include "mcdn/nfor.h"
#include "oidn/oidn_steps.h"
#include "skip/converged_tiles.h"

namespace mcdn {

using OIIO::Strutil::fmt::format;
namespace Filesystem = OIIO::Filesystem;

namespace {

// ---- weights --------------------------------------------------------------------------

// OIDN's model for the inputs there are (it has none for a normal without an albedo);
// `clean`: for prefiltered ones (OidnOptions::prefilter).
std::string model_name(bool albedo, bool normal, bool clean = false)
{
    return albedo && normal ? (clean ? "rt_hdr_calb_cnrm" : "rt_hdr_alb_nrm")
           : albedo         ? "rt_hdr_alb"
                            : "rt_hdr";
}

// A file's weights, read once per process while the file stays the same (SURE runs the
// denoiser K + 1 times, a chain once per band).
bool cached_weights(std::shared_ptr<const nn::Weights>& weights, const std::string& path,
                    std::string& error)
{
    static std::mutex mutex;
    static std::map<std::string, std::pair<std::string, std::shared_ptr<const nn::Weights>>> cache;
    const std::string stamp =
        format("{} {}", Filesystem::file_size(path), int64_t(Filesystem::last_write_time(path)));
    std::lock_guard<std::mutex> lock(mutex);
    auto& entry = cache[path];
    if (entry.second && entry.first == stamp) {
        weights = entry.second;
        return true;
    }
    auto read = std::make_shared<nn::Weights>();
    if (!oidn_net::read_tza(path, *read, error))
        return false;
    entry = { stamp, read };
    weights = read;
    return true;
}

// The inputs a network reads, by its first convolution's input channels.
bool network_inputs(const nn::Weights& weights, bool& albedo, bool& normal, std::string& error)
{
    const nn::NamedTensor* first = weights.find("enc_conv0.weight");
    const int channels = first && first->shape.size() == 4 ? first->shape[1] : 0;
    albedo = channels >= 6;
    normal = channels == 9;
    if (channels == 3 || channels == 6 || channels == 9)
        return true;
    error = format("{}: reads {} input channels; oidn runs OIDN's HDR colour models (3: "
                   "colour, 6: + albedo, 9: + normal)",
                   weights.path, channels);
    return false;
}

// ---- one tile -------------------------------------------------------------------------

/// The frame's channels a network reads, and how.
struct Inputs {
    int color[3], albedo[3], normal[3];
    bool has_albedo = false, has_normal = false;
    float exposure = 1;
    /// Heavy-tailed pixels (frame plane index, ascending) and the colour they enter as.
    std::vector<uint32_t> outliers;
    std::vector<std::array<float, 3>> outlier_color;
};

/// OidnOptions::outliers: the heavy-tailed pixels of src by NFOR's rule and thresholds
/// (outliers/outliers.h), with their neighbourhood's median colour; none without the
/// colour's variance.
void find_outliers(Inputs& in, const ImageBuf& src, const AovSet& aovs,
                   const ConvergedTiles& converged, int nthreads)
{
    if (!aovs.has(Role::ColorVariance))
        return;
    ColorPlanes color;
    read_color_planes(color, src, aovs, false);
    FrameFacts facts;
    const ColorSums frame = frame_facts(facts, src.spec()) ? facts.color : color_sums(color);
    const NforOptions nfor;  // the same thresholds as NFOR's and the CNN's
    const OutlierRule rule = outlier_rule(nfor.outlier_sigma, nfor.outlier_variance_ratio,
                                          nfor.outlier_level_ratio, frame);
    std::vector<ExtraPlanes> no_extras;
    const OutlierPixels found = take_out_outliers(color.mean, color.variance, nullptr, nullptr,
                                                  no_extras, converged, rule, nthreads);
    for (uint32_t i : found.pixels) {
        in.outliers.push_back(i);
        in.outlier_color.push_back(
            { color.mean[0].px[i], color.mean[1].px[i], color.mean[2].px[i] });
    }
}

/// The frame's planes the tiles of a pass read (tile_input), taken before the pass writes:
/// in place (the chain's own frame) a pass writes the channels it reads, and a tile's window
/// reads its neighbours' cores. 9 floats a pixel, where a copy of the frame held all of its
/// channels; tiles read them along rows.
struct InputPlanes {
    Plane color[3], albedo[3], normal[3];
};

/// The albedo and normal of `in` (never written by the op), once for every pass.
void read_features(InputPlanes& planes, const ImageBuf& src, const Inputs& in, int nthreads)
{
    std::vector<PlaneRead> reads;
    for (int c = 0; c < 3; ++c) {
        if (in.has_albedo)
            reads.push_back({ in.albedo[c], &planes.albedo[c] });
        if (in.has_normal)
            reads.push_back({ in.normal[c], &planes.normal[c] });
    }
    read_planes(src, reads, {}, nthreads);
}

// ---- the features' prefilters (OidnOptions::prefilter) --------------------------------

/// OIDN's network for one auxiliary feature (rt_alb, rt_nrm), read beside the model.
bool prefilter_net(nn::Net& net, const std::string& model_path, const char* name,
                   std::string& error)
{
    const std::string folder = Filesystem::parent_path(model_path);
    const std::string path = (folder.empty() ? std::string(".") : folder) + "/" + name + ".tza";
    if (!Filesystem::is_regular(path)) {
        error = format("prefilter=1 reads OIDN's albedo and normal prefilters (rt_alb.tza, "
                       "rt_nrm.tza) beside {}: there is no {}",
                       model_path, path);
        return false;
    }
    std::shared_ptr<const nn::Weights> weights;
    if (!cached_weights(weights, path, error) || !oidn_net::build_unet(net, *weights, error))
        return false;
    bool albedo = false, normal = false;
    if (!network_inputs(*weights, albedo, normal, error) || albedo) {
        error = format("{}: not a prefilter of one feature (3 input channels)", path);
        return false;
    }
    return true;
}

/// `input` shaped to `window` with `channels` channels, in the storage of the last tile (the
/// caller writes every value): fresh pages cost a fault and a clear each.
void shape_input(nn::Tensor& input, const Rect& window, int channels)
{
    input.height = window.height();
    input.width = window.width();
    input.channels = channels;
    if (input.data.size() < input.size())
        input.data.resize(input.size());
}

/// Channel `to` of the input's row `wy`: `plane` on the window's columns of frame row
/// window.y0 + wy, through `transform`. The window's coordinates are those of the frame
/// extended to a multiple of the network's alignment: rows and columns past the frame repeat
/// its last ones.
template <class Transform>
void read_window_row(nn::Tensor& input, int wy, int to, const Plane& plane, const Rect& window,
                     Transform transform)
{
    const float* row = plane.row(std::min(window.y0 + wy, plane.height - 1));
    for (int x = window.x0; x < window.x1; ++x)
        input.at(wy, x - window.x0, to) = transform(row[std::min(x, plane.width - 1)]);
}

/// A prefilter's input on `window`: the albedo clamped to [0, 1] through the sRGB curve; the
/// normal clamped to [-1, 1] and mapped to [0, 1].
void feature_input(nn::Tensor& input, const Plane (&feature)[3], bool albedo, const Rect& window)
{
    shape_input(input, window, 3);
    nn::parallel_rows(window.height(), [&](int wy) {
        for (int c = 0; c < 3; ++c)
            read_window_row(input, wy, c, feature[c], window, [albedo](float v) {
                return albedo ? oidn_net::srgb_forward(std::clamp(v, 0.0f, 1.0f))
                              : std::clamp(v, -1.0f, 1.0f) * 0.5f + 0.5f;
            });
    });
}

/// The prefilter's output on the frame pixels `rect` back into the feature's range: clamped
/// at 0, then the albedo through the sRGB curve's inverse, the normal mapped to [-1, 1]; both
/// at most 1.
void write_feature(Plane (&clean)[3], bool albedo, const nn::Tensor& result, const Rect& window,
                   const Rect& rect)
{
    nn::parallel_rows(rect.height(), [&](int ry) {
        const int y = rect.y0 + ry;
        for (int x = rect.x0; x < rect.x1; ++x) {
            const float* value = result.pixel(y - window.y0, x - window.x0);
            for (int c = 0; c < 3; ++c) {
                const float v = value[c] > 0.0f ? value[c] : 0.0f;  // NaN too
                clean[c](x, y) = albedo ? std::min(oidn_net::srgb_inverse(v), 1.0f)
                                        : std::min(v, 1.0f) * 2.0f - 1.0f;
            }
        }
    });
}

/// The albedo and normal of `planes` replaced by the prefilters' estimates on `area` (frame
/// coordinates: where the model's windows read them); elsewhere they stay as rendered. Each
/// prefilter's buffers are freed before the next network runs.
bool prefilter_features(InputPlanes& planes, const std::string& model_path, const ImageSpec& spec,
                        ROI area, int tile_size, int nthreads, std::string& error)
{
    for (bool albedo : { true, false }) {
        nn::Net net;
        if (!prefilter_net(net, model_path, albedo ? "rt_alb" : "rt_nrm", error))
            return false;
        std::vector<nn::Tile> tiles;
        if (!network_tiles(tiles, net, ConvergedTiles(), tile_size, true, spec, area, error))
            return false;
        Plane(&feature)[3] = albedo ? planes.albedo : planes.normal;
        Plane clean[3] = { feature[0], feature[1], feature[2] };
        std::vector<nn::Tensor> input(1), result;
        const bool ran = nn::with_threads(nthreads, [&] {
            return nn::for_each_tile(int(tiles.size()), 1, [&](int index, int) {
                const nn::Tile& tile = tiles[size_t(index)];
                feature_input(input[0], feature, albedo, tile.window);
                std::string tile_error;
                if (!net.run(input, result, tile_error)) {
                    error = format("oidn: prefilter: {}", tile_error);
                    return false;
                }
                write_feature(clean, albedo, result[0], tile.window,
                              output_rect(tile.core, spec, area));
                return true;
            });
        });
        if (!ran)
            return false;
        for (int c = 0; c < 3; ++c)
            feature[c] = std::move(clean[c]);
    }
    return true;
}

/// A pass's colour as rendered.
void read_color(InputPlanes& planes, const ImageBuf& src, const Inputs& in, int nthreads)
{
    read_planes(src,
                { { in.color[0], &planes.color[0] },
                  { in.color[1], &planes.color[1] },
                  { in.color[2], &planes.color[2] } },
                {}, nthreads);
}

/// Its heavy-tailed pixels then enter as their neighbourhood's colour (find_outliers).
void enter_outliers(InputPlanes& planes, const Inputs& in)
{
    for (size_t k = 0; k < in.outliers.size(); ++k)
        for (int c = 0; c < 3; ++c)
            planes.color[c].px[in.outliers[k]] = in.outlier_color[k][size_t(c)];
}

/// The network's input on `window` (read_window_row). False when no colour value enters
/// above 0: no light anywhere in the window (a light pass that sees none there, an empty
/// background), whose result is 0 without the network (run_passes).
bool tile_input(nn::Tensor& input, const InputPlanes& planes, const Inputs& in, const Rect& window)
{
    shape_input(input, window, 3 + 3 * in.has_albedo + 3 * in.has_normal);
    // Rows on the network's threads; each row says whether it saw light.
    std::vector<char> lit(size_t(window.height()), 0);
    nn::parallel_rows(window.height(), [&](int wy) {
        bool seen = false;
        for (int c = 0; c < 3; ++c)
            read_window_row(input, wy, c, planes.color[c], window, [&](float v) {
                const float light = std::clamp(v * in.exposure, 0.0f, FLT_MAX);
                seen |= light > 0.0f;
                return oidn_net::pu_forward(light);
            });
        for (int c = 0; c < 3 && in.has_albedo; ++c)
            read_window_row(input, wy, 3 + c, planes.albedo[c], window,
                            [](float v) { return std::clamp(v, 0.0f, 1.0f); });
        for (int c = 0; c < 3 && in.has_normal; ++c)
            read_window_row(input, wy, 6 + c, planes.normal[c], window,
                            [](float v) { return std::clamp(v, -1.0f, 1.0f) * 0.5f + 0.5f; });
        lit[size_t(wy)] = seen;
    });
    return std::find(lit.begin(), lit.end(), 1) != lit.end();
}

/// One run of the network over the frame: the beauty, or an extra AOV in the colour's place.
struct Pass {
    Inputs in;
    std::vector<int> out;   // dst's channels it writes
    std::string partition;  // an extra's set (AovSet::Extra::partition)
};

/// What the rendered extras of a set (AovSet::Extra::partition) leave of its beauty: the
/// light in none of them (0 where they partition it), per colour channel, in double as it is
/// summed; taken from the render's planes before the passes write (run_passes).
struct SetRemainder {
    std::string partition;
    std::vector<double> rgb[3];
};

/// The denoised extras still add up as the rendered ones did, each set of them on its own:
/// where the input's extras of a set sum to its beauty less a remainder R (SetRemainder), the
/// result's sum to the denoised beauty less R, the difference shared among the set's extras
/// by their denoised magnitude (equally where all are 0). Inside `where`, not on converged
/// tiles (which are the render). `passes` is the beauty's and then one set's.
void keep_set_summing(ImageBuf& dst, const SetRemainder& remainder,
                      const std::vector<const Pass*>& passes, const ROI& where,
                      const ConvergedTiles& converged)
{
    const ImageSpec& spec = dst.spec();
    float* pixels = const_cast<float*>(float_frame_pixels(dst));
    const size_t n = passes.size() - 1;
    for (int y = where.ybegin - spec.y; y < where.yend - spec.y; ++y)
        for (int x = where.xbegin - spec.x; x < where.xend - spec.x; ++x) {
            if (converged.pixel(x, y))
                continue;
            const size_t i = size_t(y) * spec.width + x;
            float* pixel = pixels + i * spec.nchannels;
            for (int c = 0; c < 3; ++c) {
                double sum_out = 0, magnitude = 0;
                for (size_t e = 1; e <= n; ++e) {
                    const int ch = passes[e]->out[size_t(c)];
                    sum_out += pixel[ch];
                    magnitude += std::abs(pixel[ch]);
                }
                const int beauty = passes[0]->out[size_t(c)];
                const double missing = pixel[beauty] - remainder.rgb[c][i] - sum_out;
                for (size_t e = 1; e <= n; ++e) {
                    float& v = pixel[passes[e]->out[size_t(c)]];
                    v = float(v + missing * (magnitude > 0 ? std::abs(v) / magnitude : 1.0 / n));
                }
            }
        }
}

void keep_extras_summing(ImageBuf& dst, const std::vector<SetRemainder>& remainders,
                         const std::vector<Pass>& passes, const ROI& where,
                         const ConvergedTiles& converged)
{
    for (const SetRemainder& remainder : remainders) {
        std::vector<const Pass*> set = { &passes[0] };
        for (size_t e = 1; e < passes.size(); ++e)
            if (passes[e].partition == remainder.partition)
                set.push_back(&passes[e]);
        keep_set_summing(dst, remainder, set, where, converged);
    }
}

/// Takes a pass's rendered colour (its planes, before it writes) out of its set's remainder;
/// the beauty's (the first pass) starts every set's.
void account_remainder(std::vector<SetRemainder>& remainders, const std::vector<Pass>& passes,
                       size_t p, const InputPlanes& planes)
{
    if (p == 0) {
        for (size_t e = 1; e < passes.size(); ++e) {
            const std::string& partition = passes[e].partition;
            if (std::any_of(remainders.begin(), remainders.end(),
                            [&](const SetRemainder& r) { return r.partition == partition; }))
                continue;
            SetRemainder r { partition, {} };
            for (int c = 0; c < 3; ++c)
                r.rgb[c].assign(planes.color[c].px.begin(), planes.color[c].px.end());
            remainders.push_back(std::move(r));
        }
        return;
    }
    for (SetRemainder& r : remainders)
        if (r.partition == passes[p].partition)
            for (int c = 0; c < 3; ++c)
                for (size_t i = 0; i < r.rgb[c].size(); ++i)
                    r.rgb[c][i] -= planes.color[c].px[i];
}

/// The network's output on the frame pixels `rect` (inside its tile's core) into dst's
/// colour channels `out`, through the inverse transform, except on converged tiles; without
/// a result (a window without light), 0.
void write_output(ImageBuf& dst, const int out[3], const nn::Tensor* result, const Rect& window,
                  const Rect& rect, float exposure, const ConvergedTiles& converged)
{
    const ImageSpec& spec = dst.spec();
    float* pixels = const_cast<float*>(float_frame_pixels(dst));
    nn::parallel_rows(rect.height(), [&](int ry) {
        const int y = rect.y0 + ry;
        for (int x = rect.x0; x < rect.x1; ++x) {
            if (converged.pixel(x, y))
                continue;
            float* pixel = pixels + (size_t(y) * spec.width + x) * spec.nchannels;
            const float* value = result ? result->pixel(y - window.y0, x - window.x0) : nullptr;
            for (int c = 0; c < 3; ++c)
                pixel[out[c]] =
                    value ? sanitize(oidn_net::pu_inverse(std::max(value[c], 0.0f)) / exposure)
                          : 0.0f;
        }
    });
}

/// The model for the AOVs present (oidn_weights: rt_hdr, rt_hdr_alb, rt_hdr_alb_nrm) and the
/// frame's channels it reads, into `in`; false with `error` when it reads an AOV the input
/// has not.
bool model_inputs(Inputs& in, std::string& path, std::shared_ptr<const nn::Weights>& weights,
                  const AovSet& aovs, const OidnOptions& options, std::string& error)
{
    const bool has_albedo = aovs.channels(Role::Albedo).size() == 3;
    const bool has_normal = aovs.channels(Role::Normal).size() == 3;
    if (options.prefilter && !(has_albedo && has_normal)) {
        error = format("prefilter=1 cleans the albedo and the normal, and the input has {} "
                       "(-v --info lists its AOVs)",
                       has_albedo   ? "no normal"
                       : has_normal ? "no albedo"
                                    : "neither");
        return false;
    }
    if (!oidn_weights(path, options, has_albedo, has_normal, error)
        || !cached_weights(weights, path, error)
        || !network_inputs(*weights, in.has_albedo, in.has_normal, error))
        return false;
    if ((in.has_albedo && !has_albedo) || (in.has_normal && !has_normal)) {
        error =
            format("{} reads {}, which the input has not (-v --info lists its AOVs); give {}.tza",
                   path, in.has_normal && !has_normal ? "a normal" : "an albedo",
                   model_name(has_albedo, has_normal && has_albedo));
        return false;
    }
    for (int c = 0; c < 3; ++c) {
        in.color[c] = aovs.channels(Role::Color)[size_t(c)];
        in.albedo[c] = in.has_albedo ? aovs.channels(Role::Albedo)[size_t(c)] : -1;
        in.normal[c] = in.has_normal ? aovs.channels(Role::Normal)[size_t(c)] : -1;
    }
    return true;
}

/// Every pass on every tile (but where a pass has no light in the window: tile_input), a tile
/// at a time with every thread in the network's layers (as OIDN itself runs): one window's buffers
/// whatever the threads, so windows can be larger and recompute less of their halo than a tile per
/// thread in the same memory (1080p, 7 passes, 2 threads: 21.0 s and 2.02 GB at tile 768,
/// against 24.3-25.3 s and 2.14 GB for tiles of 512 on two workers). Each pass reads its
/// planes (InputPlanes) before it writes, so the op runs in the chain's own frame without a
/// copy of it (then 19.8 s and 1.63 GB, two windows of 1072 × 1088 at tile 1024).
bool run_passes(nn::Net& net, const std::string& path, const std::vector<nn::Tile>& tiles,
                const std::vector<Pass>& passes, InputPlanes& planes, const ImageBuf& src,
                ImageBuf& dst, ROI where, const ConvergedTiles& converged, float exposure,
                const ProgressCallback& callback, int nthreads, std::string& error)
{
    ProgressCounter progress(callback, "oidn", int(tiles.size() * passes.size()));
    std::mutex failed;
    std::vector<SetRemainder> remainders;
    std::vector<nn::Tensor> input(1), result;
    for (size_t p = 0; p < passes.size(); ++p) {
        const Pass& pass = passes[p];
        read_color(planes, src, pass.in, nthreads);
        account_remainder(remainders, passes, p, planes);
        enter_outliers(planes, pass.in);
        const bool ran = nn::with_threads(nthreads, [&] {
            return nn::for_each_tile(int(tiles.size()), 1, [&](int index, int) {
                const nn::Tile& tile = tiles[size_t(index)];
                std::string tile_error;
                const bool lit = tile_input(input[0], planes, pass.in, tile.window);
                if (lit && !net.run(input, result, tile_error)) {
                    error = format("oidn: '{}': {}", path, tile_error);
                    return false;
                }
                write_output(dst, pass.out.data(), lit ? &result[0] : nullptr, tile.window,
                             output_rect(tile.core, src.spec(), where), exposure, converged);
                return progress.advance(error, failed);
            });
        });
        if (!ran)
            return false;
    }
    keep_extras_summing(dst, remainders, passes, where, converged);
    return true;
}

// ---- the op ---------------------------------------------------------------------------

bool oidn_in_working_space(ImageBuf& dst, const ImageBuf& src, const OidnOptions& options, ROI roi,
                           int nthreads)
{
    // In place the passes read the planes they write first (run_passes); a colour-only probe
    // frame (made anew by prepare_denoiser_output) or one not of floats in memory is copied.
    const bool color_only = src.spec().get_int_attribute(kColorOnlyAttribute, 0) == 1;
    if (&dst == &src && (color_only || !float_frame_pixels(src))) {
        const ImageBuf render = src.copy(OIIO::TypeDesc::FLOAT);
        return oidn_in_working_space(dst, render, options, roi, nthreads);
    }
    StageTrace trace("oidn");
    AovSet aovs;
    std::string error;
    if (!prepare_denoiser_output(dst, src, options.aovs, aovs, "oidn", color_only, nthreads))
        return false;
    if (!float_frame_pixels(dst)) {
        dst.errorfmt("oidn: the output frame is not in memory");
        return false;
    }
    trace.mark("copy src to dst");
    Inputs in;
    std::string path;
    std::shared_ptr<const nn::Weights> weights;
    if (!model_inputs(in, path, weights, aovs, options, error)) {
        dst.errorfmt("oidn: {}", error);
        return false;
    }
    const int out[3] = { color_only ? 0 : in.color[0], color_only ? 1 : in.color[1],
                         color_only ? 2 : in.color[2] };
    const ConvergedTiles converged = converged_tiles_of(src, aovs, options.skip);
    if (converged.all())
        return true;
    if (options.outliers == OidnOptions::Outliers::Drop)
        find_outliers(in, src, aovs, converged, nthreads);
    // The exposure of the whole frame (a band of a larger one carries it).
    FrameFacts facts;
    in.exposure = frame_facts(facts, src.spec()) && facts.has_exposure
                      ? facts.exposure
                      : autoexposure(src, in.color);

    trace.mark("weights, converged tiles, exposure");
    nn::Net net;
    if (!oidn_net::build_unet(net, *weights, error)) {
        dst.errorfmt("oidn: {}", error);
        return false;
    }
    const ROI where = output_roi(src, roi);
    std::vector<nn::Tile> tiles;
    if (!network_tiles(tiles, net, converged, options.tile_size, true, src.spec(), where, error)) {
        dst.errorfmt("oidn: {}", error);
        return false;
    }
    // The beauty, then each extra AOV (a light group: its own run of the network, with the
    // beauty's exposure and features), into its channels of dst.
    std::vector<Pass> passes = { { in, { out[0], out[1], out[2] }, {} } };
    if (!color_only && denoises_extras(options.denoise_extras, src))
        for (const AovSet::Extra& extra : aovs.extras())
            if (extra.channels.size() == 3) {
                Pass pass { in, extra.channels, extra.partition };
                pass.in.outliers.clear();
                pass.in.outlier_color.clear();
                for (int c = 0; c < 3; ++c)
                    pass.in.color[c] = extra.channels[size_t(c)];
                passes.push_back(pass);
            }
    // The features, once for every pass; cleaned by OIDN's prefilters first where asked, on
    // the model's reach of `where`.
    InputPlanes planes;
    read_features(planes, src, in, nthreads);
    if (options.prefilter) {
        const int reach = net.receptive_radius();
        const ROI frame = src.roi();
        const ROI area(
            std::max(where.xbegin - reach, frame.xbegin), std::min(where.xend + reach, frame.xend),
            std::max(where.ybegin - reach, frame.ybegin), std::min(where.yend + reach, frame.yend));
        if (!prefilter_features(planes, path, src.spec(), area, options.tile_size, nthreads,
                                error)) {
            dst.errorfmt("oidn: {}", error);
            return false;
        }
        trace.mark("prefilters");
    }
    const bool ran = run_passes(net, path, tiles, passes, planes, src, dst, where, converged,
                                in.exposure, options.progress, nthreads, error);
    if (!ran) {
        dst.errorfmt("{}", error);
        return false;
    }
    trace.mark("network tiles");
    return true;
}

}  // namespace

std::string oidn_weights_dir()
{
    return install_paths().data_dir + "/oidn";
}

bool oidn_weights(std::string& path, const OidnOptions& options, bool has_albedo, bool has_normal,
                  std::string& error)
{
    const char* env = std::getenv("MCDN_OIDN_WEIGHTS");
    const std::string given = !options.weights.empty() ? options.weights
                              : env && *env            ? std::string(env)
                                                       : oidn_weights_dir();
    const std::string model =
        model_name(has_albedo, has_normal, options.prefilter && has_albedo && has_normal) + ".tza";
    path = Filesystem::is_directory(given) ? given + "/" + model : given;
    if (Filesystem::is_regular(path))
        return true;
    error = format("no OIDN weights at {} (looked for {} by weights=FILE or a folder, then "
                   "$MCDN_OIDN_WEIGHTS, then {}). mcdenoise does not ship them: they are "
                   "Intel Open Image Denoise's (Apache 2.0), in RenderKit/oidn-weights on "
                   "GitHub or the weights/ folder of an OIDN 2.x source package",
                   path, model, oidn_weights_dir());
    return false;
}

int receptive_radius(const OidnOptions& options)
{
    // Every model has the one UNet: any of them says.
    for (bool albedo : { true, false }) {
        std::string path, error;
        std::shared_ptr<const nn::Weights> weights;
        nn::Net net;
        if (oidn_weights(path, options, albedo, albedo, error)
            && cached_weights(weights, path, error) && oidn_net::build_unet(net, *weights, error))
            // Outliers are decided on the 5×5 neighbourhood of the input; the prefilters'
            // features reach as far again.
            return net.receptive_radius() * (options.prefilter ? 2 : 1)
                   + (options.outliers == OidnOptions::Outliers::Drop ? OutlierRule::radius : 0);
    }
    return -1;
}

bool oidn(ImageBuf& dst, const ImageBuf& src, const OidnOptions& options, ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "oidn"))
        return false;
    if (!run_in_working_space(dst, src, options.aovs, "oidn", [&](ImageBuf& d, const ImageBuf& s) {
            return oidn_in_working_space(d, s, options, roi, nthreads);
        }))
        return false;
    dst.specmod().attribute(kDenoiserAttribute, "oidn");
    return true;
}

ImageBuf oidn(const ImageBuf& src, const OidnOptions& options, ROI roi, int nthreads)
{
    ImageBuf dst;
    oidn(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
