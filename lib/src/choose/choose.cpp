// Choosing between two denoisers by their SURE (mcdn/choose.h): the render rebuilt from
// sure's record, the other denoiser and its SURE on it, the weight map, the blend.
#include "mcdn/choose.h"

#include <algorithm>
#include <cmath>

#include <OpenImageIO/strutil.h>

#include "core/channels.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "core/progress.h"
#include "core/trace.h"
#include "ops/window_sums.h"
#include "skip/converged_tiles.h"
#include "sure/sure_steps.h"

namespace mcdn {

namespace {

using OIIO::Strutil::fmt::format;

// The relMSE offset: a pixel's error counts relative to its value, as the metric does.
constexpr float kRelativeOffset = 0.01f;
// The least a window's summed relative SURE counts as (mcdn/choose.h).
constexpr double kLeastError = 1e-9;

// Where one RGB image and its SURE are in a frame written by sure.
struct Candidate {
    int y[3], sure[3], divergence[3], residual[3];
};

struct ChooseChannels {
    Candidate a, b;   // a in src, b in other's result
    int x[3];         // the render (noisy.*) in src
    int variance[3];  // the variance of its mean in src
    // Each RGB extra's rendered value (noisy.<channel>, as sure recorded it) and its channel,
    // in src.
    std::vector<std::pair<int, int>> recorded_extras;
    // Each RGB extra's channel in src and in other's result.
    std::vector<std::pair<int, int>> extras;
};

bool find_candidate(Candidate& c, const ImageSpec& spec, const AovSet& aovs, std::string& error)
{
    for (int k = 0; k < 3; ++k) {
        c.y[k] = aovs.channels(Role::Color)[k];
        const std::pair<int*, const char*> named[] = {
            { &c.sure[k], sure_channels::kSure[k] },
            { &c.divergence[k], sure_channels::kDivergence[k] },
            { &c.residual[k], sure_channels::kResidual[k] },
        };
        for (const auto& [channel, name] : named)
            if ((*channel = spec.channelindex(name)) < 0) {
                error = format("needs what --sure adds (run --sure before it: --cnn --sure "
                               "--choose); the input has no '{}'",
                               name);
                return false;
            }
    }
    return true;
}

// The render as sure recorded it: src with the colour and each RGB extra put back from
// noisy.* (a denoiser before sure writes nothing else).
bool rebuild_render(ImageBuf& render, const ImageBuf& src, const ChooseChannels& ch, int nthreads,
                    std::string& error)
{
    render = copy_with_channels(src, {}, {}, nthreads);
    if (!render.localpixels()) {
        error = format("out of memory for a copy of the {}x{} frame of {} channels",
                       src.spec().width, src.spec().height, src.spec().nchannels);
        return false;
    }
    std::vector<std::pair<int, int>> from_to = ch.recorded_extras;
    for (int k = 0; k < 3; ++k)
        from_to.emplace_back(ch.x[k], ch.a.y[k]);
    const int n = render.nchannels();
    float* px = static_cast<float*>(render.localpixels());
    const size_t npixels = render.spec().image_pixels();
    for (size_t p = 0; p < npixels; ++p)
        for (const auto& [from, to] : from_to)
            px[p * n + to] = px[p * n + from];
    return true;
}

// Where b may weigh (ChooseOptions::max_noise): 1 where the render's relative variance
// Var / (y_a^2 + 0.01), averaged over R, G, B and the window, is below max_noise, else 0;
// 1 everywhere without a bound.
Plane trusted_windows(const ImageBuf& src, const ChooseChannels& ch, const ChooseOptions& options,
                      int nthreads)
{
    if (options.max_noise <= 0)
        return Plane(src.spec().width, src.spec().height, 1.0f);
    Plane noise(src.spec().width, src.spec().height);
    for (int k = 0; k < 3; ++k) {
        Plane ya, variance;
        read_planes(src, { { ch.a.y[k], &ya }, { ch.variance[k], &variance, true } }, {}, nthreads);
        for (size_t i = 0; i < noise.size(); ++i) {
            const float r = variance.px[i] / (ya.px[i] * ya.px[i] + kRelativeOffset);
            noise.px[i] += std::isfinite(r) ? r / 3.0f : INFINITY;  // never trusted
        }
    }
    const Plane mean =
        separable_window_sum(noise, std::vector<double>(size_t(2 * options.window_radius + 1), 1.0),
                             options.window_radius, true);
    for (size_t i = 0; i < noise.size(); ++i)
        noise.px[i] = mean.px[i] < options.max_noise ? 1.0f : 0.0f;
    return noise;
}

// The render's converged tiles (those sure and the other denoiser skip: mcdn/skip.h) and
// those with no trusted pixel within `reach`: b is read only within the window of a trusted
// pixel (its error sums there; the blend reaches less far), so the other denoiser and its
// probes pass the rest through.
ConvergedTiles skipped_tiles(const ImageBuf& render, const Plane& trusted, const AovSet& aovs,
                             const ChooseOptions& options, int reach)
{
    ConvergedTiles m = converged_tiles_of(render, aovs, options.sure.skip);
    if (m.converged.empty()) {
        m = empty_tile_map(trusted.width, trusted.height);
        m.converged.assign(size_t(m.tiles_x) * m.tiles_y, 0);
    }
    const Plane near =
        separable_window_sum(trusted, std::vector<double>(size_t(2 * reach + 1), 1.0), reach);
    for (int ty = 0; ty < m.tiles_y; ++ty)
        for (int tx = 0; tx < m.tiles_x; ++tx) {
            bool needed = false;
            for (int y = ty * kConvergedTileSize;
                 y < std::min((ty + 1) * kConvergedTileSize, near.height) && !needed; ++y)
                for (int x = tx * kConvergedTileSize;
                     x < std::min((tx + 1) * kConvergedTileSize, near.width) && !needed; ++x)
                    needed = near(x, y) > 0.0f;
            if (!needed)
                m.converged[size_t(ty) * m.tiles_x + tx] = 1;
        }
    return m;
}

// w of mcdn/choose.h: each candidate's SURE relative to (ybar^2 + 0.01 + Var), summed over
// the window; b's share of the inverse errors; smoothed.
Plane choice_weight(const ImageBuf& src, const ImageBuf& other, const ChooseChannels& ch,
                    const Plane& trusted, const ChooseOptions& options, int nthreads)
{
    Plane ea, eb;
    for (int k = 0; k < 3; ++k) {
        Plane ya, yb, sa, sb, variance;
        read_planes(
            src, { { ch.a.y[k], &ya }, { ch.a.sure[k], &sa }, { ch.variance[k], &variance, true } },
            {}, nthreads);
        read_planes(other, { { ch.b.y[k], &yb }, { ch.b.sure[k], &sb } }, {}, nthreads);
        if (k == 0)
            ea = eb = Plane(ya.width, ya.height);
        for (size_t i = 0; i < ea.size(); ++i) {
            const float mean = 0.5f * (ya.px[i] + yb.px[i]);
            const float scale = mean * mean + kRelativeOffset + variance.px[i];
            const float a = sa.px[i] / scale, b = sb.px[i] / scale;
            ea.px[i] += std::isfinite(a) ? a : 0.0f;
            eb.px[i] += std::isfinite(b) ? b : 0.0f;
        }
    }
    const std::vector<double> window(size_t(2 * options.window_radius + 1), 1.0);
    const Plane sum_a = separable_window_sum(ea, window, options.window_radius),
                sum_b = separable_window_sum(eb, window, options.window_radius);
    for (size_t i = 0; i < ea.size(); ++i) {
        // SURE summed over a window can still come out at or below 0 (it is unbiased, not
        // positive): such a candidate is as good as the estimate can tell.
        const double a = std::max(double(sum_a.px[i]), kLeastError),
                     b = std::max(double(sum_b.px[i]), kLeastError);
        ea.px[i] = trusted.px[i] * float(a / (a + b));
    }
    return separable_window_sum(ea, std::vector<double>(size_t(2 * options.blend_radius + 1), 1.0),
                                options.blend_radius, true);
}

// dst's colour, extras and SURE channels: a + w (b - a); the residual against x exactly;
// SURE from the residual, the blended divergence and the variance (SURE_a's own terms).
void blend(ImageBuf& dst, const ImageBuf& other, const ChooseChannels& ch, const Plane& w,
           int nthreads)
{
    const ROI roi = dst.roi();
    for (int k = 0; k < 3; ++k) {
        Plane ya, yb, da, db, ra, sa, x;
        read_planes(dst,
                    { { ch.a.y[k], &ya },
                      { ch.a.divergence[k], &da },
                      { ch.a.residual[k], &ra },
                      { ch.a.sure[k], &sa },
                      { ch.x[k], &x } },
                    {}, nthreads);
        read_planes(other, { { ch.b.y[k], &yb }, { ch.b.divergence[k], &db } }, {}, nthreads);
        for (size_t i = 0; i < w.size(); ++i) {
            const float t = w.px[i];
            // SURE_a = r_a + 2 div_a - var: the variance as sure counted it.
            const float variance = ra.px[i] + 2.0f * da.px[i] - sa.px[i];
            ya.px[i] += t * (yb.px[i] - ya.px[i]);
            da.px[i] += t * (db.px[i] - da.px[i]);
            const float r = ya.px[i] - x.px[i];
            ra.px[i] = r * r;
            sa.px[i] = ra.px[i] + 2.0f * da.px[i] - variance;
        }
        write_planes(dst,
                     { { ch.a.y[k], &ya },
                       { ch.a.divergence[k], &da },
                       { ch.a.residual[k], &ra },
                       { ch.a.sure[k], &sa } },
                     roi);
    }
    for (const auto& [in_dst, in_other] : ch.extras) {
        Plane a, b;
        read_planes(dst, { { in_dst, &a } }, {}, nthreads);
        read_planes(other, { { in_other, &b } }, {}, nthreads);
        for (size_t i = 0; i < w.size(); ++i)
            a.px[i] += w.px[i] * (b.px[i] - a.px[i]);
        write_planes(dst, { { in_dst, &a } }, roi);
    }
}

}  // namespace

int receptive_radius(const ChooseOptions& options)
{
    return options.window_radius + options.blend_radius;
}

bool choose(ImageBuf& dst, const ImageBuf& src, const Denoiser& other, const ChooseOptions& options,
            ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "choose"))
        return false;
    if (options.window_radius < 0 || options.blend_radius < 0) {
        dst.errorfmt("choose: window and blend radii must be at least 0");
        return false;
    }
    StageTrace trace("choose");
    AovSet aovs;
    std::string error;
    ChooseChannels ch;
    if (!check_op_input(src, options.aovs, aovs, "choose", error)
        || !aovs.require({ Role::Color, Role::ColorVariance }, src.spec(), error)
        || !find_candidate(ch.a, src.spec(), aovs, error)) {
        dst.errorfmt("{}", error.compare(0, 8, "choose: ") == 0 ? error : "choose: " + error);
        return false;
    }
    if (options.other_needs_halves && (!aovs.has(Role::ColorA) || !aovs.has(Role::ColorB))) {
        dst.errorfmt("choose: needs the colour's half buffers (-i:as=halfA, -i:as=halfB; a "
                     "Tungsten folder has them): NFOR beside the denoiser reads them");
        return false;
    }
    for (int k = 0; k < 3; ++k) {
        ch.x[k] = src.spec().channelindex(sure_channels::kNoisy[k]);
        ch.variance[k] = aovs.channels(Role::ColorVariance)[k];
    }
    if (ch.x[0] < 0 || ch.x[1] < 0 || ch.x[2] < 0) {
        dst.errorfmt("choose: needs what --sure adds; the input has no '{}'",
                     sure_channels::kNoisy[0]);
        return false;
    }
    for (const AovSet::Extra& extra : aovs.extras())
        if (extra.channels.size() == 3)
            for (size_t k = 0; k < 3; ++k)
                if (const int noisy =
                        src.spec().channelindex(sure_channels::noisy_extra(extra.names[k]));
                    noisy >= 0)
                    ch.recorded_extras.emplace_back(noisy, extra.channels[k]);
    // Two steps: b with its SURE (K + 1 runs of other), then the choice and the blend.
    ProgressCounter progress(options.progress, "choose", 2);
    const Plane trusted = trusted_windows(src, ch, options, nthreads);
    if (std::find(trusted.px.begin(), trusted.px.end(), 1.0f) == trusted.px.end()) {
        // b weighs nowhere: the result is src's, without running other.
        if (&dst != &src && !prepare_op(dst, src, options.aovs, aovs, "choose", nthreads))
            return false;
        dst.specmod().attribute(kChooseShareAttribute, 0.0f);
        if (options.output_weight)
            write_plane(dst, add_channels(dst, { "choose.weight" })[0], trusted, dst.roi());
        trace.mark("the other denoiser: not run (max_noise)");
        if (!progress.advance() || !progress.advance()) {
            dst.errorfmt("{}", progress.error());
            return false;
        }
        return true;
    }
    ImageBuf render, b;
    if (!rebuild_render(render, src, ch, nthreads, error)) {
        dst.errorfmt("choose: {}", error);
        return false;
    }
    if (options.max_noise > 0 && options.sure.skip.enabled)
        render.specmod().attribute(kConvergedAttribute,
                                   encode_converged_tiles(skipped_tiles(
                                       render, trusted, aovs, options, options.window_radius)));
    SureOptions sure_options = options.sure;
    sure_options.aovs = options.aovs;
    sure_options.denoiser_radius = options.other_radius;
    if (options.progress)
        sure_options.progress = [&](const std::string&, float fraction) {
            return options.progress("choose", 0.5f * fraction);
        };
    // The rebuilt render is choose's own: sure probes it in place (no copy of the frame).
    if (!sure_probing_src(b, render, other, sure_options, roi, nthreads)) {
        dst.errorfmt("choose: {}", b.geterror());
        return false;
    }
    render = ImageBuf();  // not reset(): b may be the render itself, moved (SureOptions)
    trace.mark("the other denoiser and its SURE");
    if (!progress.advance()) {
        dst.errorfmt("{}", progress.error());
        return false;
    }
    AovSet b_aovs;  // b's channels by name: sure may order them otherwise
    if (!resolve_aovs(b_aovs, options.aovs, b.spec(), error)
        || !find_candidate(ch.b, b.spec(), b_aovs, error)) {
        dst.errorfmt("choose: {}", error);
        return false;
    }
    for (const auto& [noisy, channel] : ch.recorded_extras)
        ch.extras.emplace_back(channel, b.spec().channelindex(src.spec().channel_name(channel)));
    const Plane w = choice_weight(src, b, ch, trusted, options, nthreads);
    if (&dst != &src && !prepare_op(dst, src, options.aovs, aovs, "choose", nthreads))
        return false;
    blend(dst, b, ch, w, nthreads);
    double share = 0;
    for (float t : w.px)
        share += t;
    dst.specmod().attribute(kChooseShareAttribute,
                            float(share / double(std::max<size_t>(1, w.size()))));
    if (options.output_weight) {
        const std::vector<int> channel = add_channels(dst, { "choose.weight" });
        write_plane(dst, channel[0], w, dst.roi());
    }
    trace.mark("the choice and the blend");
    if (!progress.advance()) {
        dst.errorfmt("{}", progress.error());
        return false;
    }
    return true;
}

ImageBuf choose(const ImageBuf& src, const Denoiser& other, const ChooseOptions& options, ROI roi,
                int nthreads)
{
    ImageBuf dst;
    choose(dst, src, other, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
