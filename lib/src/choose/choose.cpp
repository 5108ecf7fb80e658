// Choosing between two denoisers by their error estimates (mcdn/choose.h): both on the
// halves (the halves' rule), the render rebuilt from sure's record, the other denoiser and
// its SURE on it, the weight map, the blend.
#include "mcdn/choose.h"

#include <algorithm>
#include <cmath>

#include <OpenImageIO/strutil.h>

#include "choose/half_render.h"
#include "core/channels.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "core/progress.h"
#include "core/trace.h"
#include "mcdn/color.h"
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

// a's image and its SURE as the blend needs them (sanitized, as read_plane reads), kept
// apart while the other denoiser runs in the frame they were in: the colour, its SURE,
// divergence and residual, and each RGB extra's value (ch.recorded_extras' order).
struct Kept {
    Plane y[3], sure[3], divergence[3], residual[3];
    std::vector<Plane> extras;
};

Kept keep_candidate(const ImageBuf& src, const ChooseChannels& ch, int nthreads)
{
    Kept a;
    std::vector<PlaneRead> reads;
    for (int k = 0; k < 3; ++k)
        for (const auto& [channel, plane] :
             { std::pair { ch.a.y[k], &a.y[k] }, std::pair { ch.a.sure[k], &a.sure[k] },
               std::pair { ch.a.divergence[k], &a.divergence[k] },
               std::pair { ch.a.residual[k], &a.residual[k] } })
            reads.push_back({ channel, plane });
    a.extras.resize(ch.recorded_extras.size());
    for (size_t e = 0; e < ch.recorded_extras.size(); ++e)
        reads.push_back({ ch.recorded_extras[e].second, &a.extras[e] });
    read_planes(src, reads, {}, nthreads);
    return a;
}

// The render as sure recorded it, made in `frame` (a float frame in memory of src's
// channels): the colour and each RGB extra put back from noisy.* (a denoiser before sure
// writes nothing else).
void rebuild_render(ImageBuf& frame, const ChooseChannels& ch)
{
    std::vector<std::pair<int, int>> from_to = ch.recorded_extras;
    for (int k = 0; k < 3; ++k)
        from_to.emplace_back(ch.x[k], ch.a.y[k]);
    const int n = frame.nchannels();
    float* px = static_cast<float*>(frame.localpixels());
    const size_t npixels = frame.spec().image_pixels();
    for (size_t p = 0; p < npixels; ++p)
        for (const auto& [from, to] : from_to)
            px[p * n + to] = px[p * n + from];
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
// the window; b's share of the inverse errors; smoothed. Var from `frame` (the render's
// variance, which no denoiser writes), b's from `other`.
Plane choice_weight(const Kept& a, const ImageBuf& frame, const ImageBuf& other,
                    const ChooseChannels& ch, const Plane& trusted, const ChooseOptions& options,
                    int nthreads)
{
    Plane ea(trusted.width, trusted.height), eb(trusted.width, trusted.height);
    for (int k = 0; k < 3; ++k) {
        Plane yb, sb, variance;
        read_planes(frame, { { ch.variance[k], &variance, true } }, {}, nthreads);
        read_planes(other, { { ch.b.y[k], &yb }, { ch.b.sure[k], &sb } }, {}, nthreads);
        const Plane &ya = a.y[k], &sa = a.sure[k];
        for (size_t i = 0; i < ea.size(); ++i) {
            const float mean = 0.5f * (ya.px[i] + yb.px[i]);
            const float scale = mean * mean + kRelativeOffset + variance.px[i];
            const float ra = sa.px[i] / scale, rb = sb.px[i] / scale;
            ea.px[i] += std::isfinite(ra) ? ra : 0.0f;
            eb.px[i] += std::isfinite(rb) ? rb : 0.0f;
        }
    }
    const std::vector<double> window(size_t(2 * options.window_radius + 1), 1.0);
    const Plane sum_a = separable_window_sum(ea, window, options.window_radius),
                sum_b = separable_window_sum(eb, window, options.window_radius);
    for (size_t i = 0; i < ea.size(); ++i) {
        // SURE summed over a window can still come out at or below 0 (it is unbiased, not
        // positive): such a candidate is as good as the estimate can tell.
        const double sa = std::max(double(sum_a.px[i]), kLeastError),
                     sb = std::max(double(sum_b.px[i]), kLeastError);
        ea.px[i] = trusted.px[i] * float(sa / (sa + sb));
    }
    return separable_window_sum(ea, std::vector<double>(size_t(2 * options.blend_radius + 1), 1.0),
                                options.blend_radius, true);
}

// What the halves' rule reads (mcdn/choose.h), per colour channel: d_H = b_H - a_H and
// the other half's residual r_H = (the other half) - a_H, for H = A, B.
struct HalvesRuns {
    Plane d[2][3], r[2][3];
};

// The half renders' AOVs resolve (an --aov override may name a half, which they lack);
// else `why`.
bool halves_resolve(const ImageBuf& src, const AovSet& aovs, const ChooseOptions& options,
                    std::string& why)
{
    HalfLayout half;
    AovSet resolved;
    return half_layout(half, src.spec(), aovs, Face::HalfA, why)
           && resolve_aovs(resolved, options.aovs, half.spec, why);
}

// a's denoiser and the other on each half of the render src holds (choose/half_render.h).
bool run_on_halves(HalvesRuns& out, const ImageBuf& src, const AovSet& aovs, const Denoiser& other,
                   const ChooseChannels& ch, const ChooseOptions& options, int nthreads,
                   std::string& error)
{
    const FrameFacts facts = render_facts(src, aovs, ch.x);
    Plane half[2][3];
    for (int k = 0; k < 3; ++k)
        read_planes(src,
                    { { aovs.channels(Role::ColorA)[size_t(k)], &half[0][k] },
                      { aovs.channels(Role::ColorB)[size_t(k)], &half[1][k] } },
                    {}, nthreads);
    for (int h = 0; h < 2; ++h) {
        ImageBuf render, a;
        if (!half_render(render, src, aovs, h == 0 ? Face::HalfA : Face::HalfB, nthreads, error))
            return false;
        set_frame_facts(render.specmod(), facts);
        const char* name = h == 0 ? "half A" : "half B";
        std::vector<int> color(3);
        for (int k = 0; k < 3; ++k)
            color[size_t(k)] = render.spec().channelindex(aovs.names(Role::Color)[size_t(k)]);
        if (!options.before(a, render)) {
            error = format("the denoiser before it, on {}: {}", name, a.geterror());
            return false;
        }
        // The other runs in the half render itself: a frame less.
        const Denoiser& other_here = options.other_on_halves ? options.other_on_halves : other;
        if (!other_here(render, render)) {
            error = format("the other denoiser, on {}: {}", name, render.geterror());
            return false;
        }
        for (int k = 0; k < 3; ++k) {
            Plane ya, yb;
            read_planes(a, { { color[size_t(k)], &ya } }, {}, nthreads);
            read_planes(render, { { color[size_t(k)], &yb } }, {}, nthreads);
            Plane& d = out.d[h][k] = yb;
            Plane& r = out.r[h][k] = half[1 - h][k];
            for (size_t i = 0; i < d.size(); ++i) {
                d.px[i] -= ya.px[i];
                r.px[i] -= ya.px[i];
            }
        }
    }
    return true;
}

// w of the halves' rule (mcdn/choose.h), smoothed; s from a, b and the render's variance
// in `frame`.
Plane halves_weight(const HalvesRuns& halves, const Kept& a, const ImageBuf& frame,
                    const ImageBuf& other, const ChooseChannels& ch, const Plane& trusted,
                    const ChooseOptions& options, int nthreads)
{
    const int width = trusted.width, height = trusted.height;
    Plane num(width, height), den(width, height), noise(width, height);
    for (int k = 0; k < 3; ++k) {
        Plane yb, variance;
        read_planes(frame, { { ch.variance[k], &variance, true } }, {}, nthreads);
        read_planes(other, { { ch.b.y[k], &yb } }, {}, nthreads);
        for (size_t i = 0; i < num.size(); ++i) {
            const float mean = 0.5f * (a.y[k].px[i] + yb.px[i]);
            const double s = double(mean) * mean + kRelativeOffset + variance.px[i];
            double n = 0, d = 0;
            for (int h = 0; h < 2; ++h) {
                const double dh = halves.d[h][k].px[i];
                n += dh * halves.r[h][k].px[i];
                d += dh * dh;
            }
            const double v = d * 2.0 * variance.px[i] / (s * s);
            if (std::isfinite(n / s) && std::isfinite(d / s) && std::isfinite(v)) {
                num.px[i] += float(n / s);
                den.px[i] += float(d / s);
                noise.px[i] += float(v);
            }
        }
    }
    const std::vector<double> window(size_t(2 * options.window_radius + 1), 1.0);
    const Plane sum_n = separable_window_sum(num, window, options.window_radius),
                sum_d = separable_window_sum(den, window, options.window_radius),
                sum_v = separable_window_sum(noise, window, options.window_radius);
    Plane w0(width, height);
    for (size_t i = 0; i < w0.size(); ++i) {
        const double n = sum_n.px[i], d = sum_d.px[i];
        const bool significant =
            n > kChooseSignificance * std::sqrt(std::max(double(sum_v.px[i]), 0.0)) && d > 0;
        w0.px[i] = significant ? trusted.px[i] * float(std::clamp(n / d, 0.0, 1.0)) : 0.0f;
    }
    return separable_window_sum(w0, std::vector<double>(size_t(2 * options.blend_radius + 1), 1.0),
                                options.blend_radius, true);
}

// dst's colour, extras and SURE channels: a + w (b - a), b read from `other` (which may be
// dst itself: each plane is read before it is written); the residual against x (noisy.*
// in dst) exactly; SURE from the residual, the blended divergence and the variance
// (SURE_a's own terms).
void blend(ImageBuf& dst, const ImageBuf& other, const Kept& a, const ChooseChannels& ch,
           const Plane& w, int nthreads)
{
    const ROI roi = dst.roi();
    for (int k = 0; k < 3; ++k) {
        Plane yb, db, x;
        read_planes(other, { { ch.b.y[k], &yb }, { ch.b.divergence[k], &db } }, {}, nthreads);
        read_planes(dst, { { ch.x[k], &x } }, {}, nthreads);
        Plane y(w.width, w.height), d(w.width, w.height), r(w.width, w.height),
            sure(w.width, w.height);
        for (size_t i = 0; i < w.size(); ++i) {
            const float t = w.px[i];
            // SURE_a = r_a + 2 div_a - var: the variance as sure counted it.
            const float variance =
                a.residual[k].px[i] + 2.0f * a.divergence[k].px[i] - a.sure[k].px[i];
            y.px[i] = a.y[k].px[i] + t * (yb.px[i] - a.y[k].px[i]);
            d.px[i] = a.divergence[k].px[i] + t * (db.px[i] - a.divergence[k].px[i]);
            const float residual = y.px[i] - x.px[i];
            r.px[i] = residual * residual;
            sure.px[i] = r.px[i] + 2.0f * d.px[i] - variance;
        }
        write_planes(dst,
                     { { ch.a.y[k], &y },
                       { ch.a.divergence[k], &d },
                       { ch.a.residual[k], &r },
                       { ch.a.sure[k], &sure } },
                     roi);
    }
    for (size_t e = 0; e < ch.extras.size(); ++e) {
        const auto& [in_dst, in_other] = ch.extras[e];
        Plane b;
        read_planes(other, { { in_other, &b } }, {}, nthreads);
        Plane blended = a.extras[e];
        for (size_t i = 0; i < w.size(); ++i)
            blended.px[i] += w.px[i] * (b.px[i] - blended.px[i]);
        write_planes(dst, { { in_dst, &blended } }, roi);
    }
}

}  // namespace

int receptive_radius(const ChooseOptions& options)
{
    return options.window_radius + options.blend_radius;
}

namespace {

bool choose_in_working_space(ImageBuf& dst, const ImageBuf& src, const Denoiser& other,
                             const ChooseOptions& options, ROI roi, int nthreads)
{
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
    // Which estimate weighs (ChooseOptions::estimate), and where not the halves, why.
    std::string why;
    if (options.estimate == ChooseEstimate::Halves) {
        if (!options.before)
            why = "no denoiser before it was given";
        else if (!aovs.has(Role::ColorA) || !aovs.has(Role::ColorB))
            why = "the render has no half buffers";
        else if (!halves_resolve(src, aovs, options, why))
            why = "the half renders' AOVs: " + why;
    }
    const bool use_halves = options.estimate == ChooseEstimate::Halves && why.empty();
    const std::string estimate = use_halves    ? "halves"
                                 : why.empty() ? "SURE"
                                               : "SURE (" + why + ")";
    // Two steps: b with its SURE (K + 1 runs of other), then the choice and the blend; the
    // halves' runs before them.
    ProgressCounter progress(options.progress, "choose", use_halves ? 3 : 2);
    const Plane trusted = trusted_windows(src, ch, options, nthreads);
    if (std::find(trusted.px.begin(), trusted.px.end(), 1.0f) == trusted.px.end()) {
        // b weighs nowhere: the result is src's, without running other.
        if (&dst != &src && !prepare_op(dst, src, options.aovs, aovs, "choose", nthreads))
            return false;
        dst.specmod().attribute(kChooseShareAttribute, 0.0f);
        dst.specmod().attribute(kChooseEstimateAttribute, estimate);
        if (options.output_weight)
            write_plane(dst, add_channels(dst, { "choose.weight" })[0], trusted, dst.roi());
        trace.mark("the other denoiser: not run (max_noise)");
        if (!progress.advance() || !progress.advance() || (use_halves && !progress.advance())) {
            dst.errorfmt("{}", progress.error());
            return false;
        }
        return true;
    }
    // a's values kept apart; the render rebuilt in dst itself where choose runs in place on
    // a frame in memory (as in a chain: no frame-sized copy), else in a copy of src. The other
    // denoiser probed there by its SURE (in place too where it can: SureOptions) makes b.
    const Kept a = keep_candidate(src, ch, nthreads);
    // The halves' runs while src is as it came (it may be dst).
    HalvesRuns halves;
    if (use_halves) {
        if (!run_on_halves(halves, src, aovs, other, ch, options, nthreads, error)) {
            dst.errorfmt("choose: {}", error);
            return false;
        }
        trace.mark("both denoisers on the halves");
        if (!progress.advance()) {
            dst.errorfmt("{}", progress.error());
            return false;
        }
    }
    const ImageSpec spec = src.spec();  // the result's: b's run leaves its own
    const bool in_place = &dst == &src && float_frame_pixels(src);
    ImageBuf copy;
    if (!in_place) {
        copy = copy_with_channels(src, {}, {}, nthreads);
        if (!copy.localpixels()) {
            dst.errorfmt("choose: out of memory for a copy of the {}x{} frame of {} channels",
                         spec.width, spec.height, spec.nchannels);
            return false;
        }
    }
    ImageBuf& render = in_place ? dst : copy;
    rebuild_render(render, ch);
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
    const void* render_pixels = render.localpixels();
    ImageBuf b;
    if (!sure_probing_src(b, render, other, sure_options, roi, nthreads)) {
        dst.errorfmt("choose: {}", b.geterror());
        return false;
    }
    // b is the render's own frame when the other denoiser ran in it (`render` is then a
    // moved-from ImageBuf, whose methods must not be called), else a frame of its own and
    // the render is as it was.
    const bool b_in_render = b.localpixels() == render_pixels;
    ImageBuf result = b_in_render ? std::move(b) : std::move(render);
    if (in_place)
        dst = ImageBuf();  // moved from: errors go on it below
    trace.mark("the other denoiser and its SURE");
    if (!progress.advance()) {
        dst.errorfmt("{}", progress.error());
        return false;
    }
    const ImageBuf& b_frame = b_in_render ? result : b;
    AovSet b_aovs;  // b's channels by name: sure may order them otherwise
    if (!resolve_aovs(b_aovs, options.aovs, b_frame.spec(), error)
        || !find_candidate(ch.b, b_frame.spec(), b_aovs, error)) {
        dst.errorfmt("choose: {}", error);
        return false;
    }
    if (result.spec().channelnames != spec.channelnames) {
        dst.errorfmt("choose: the other denoiser changed the frame's channels");
        return false;
    }
    result.specmod() = spec;
    for (const auto& [noisy, channel] : ch.recorded_extras)
        ch.extras.emplace_back(channel, b_frame.spec().channelindex(spec.channel_name(channel)));
    const Plane w = use_halves
                        ? halves_weight(halves, a, result, b_frame, ch, trusted, options, nthreads)
                        : choice_weight(a, result, b_frame, ch, trusted, options, nthreads);
    blend(result, b_frame, a, ch, w, nthreads);
    b = ImageBuf();
    dst = std::move(result);
    double share = 0;
    for (float t : w.px)
        share += t;
    dst.specmod().attribute(kChooseShareAttribute,
                            float(share / double(std::max<size_t>(1, w.size()))));
    dst.specmod().attribute(kChooseEstimateAttribute, estimate);
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

}  // namespace

bool choose(ImageBuf& dst, const ImageBuf& src, const Denoiser& other, const ChooseOptions& options,
            ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "choose"))
        return false;
    if (options.window_radius < 0 || options.blend_radius < 0) {
        dst.errorfmt("choose: window and blend radii must be at least 0");
        return false;
    }
    // In the working space, as sure and the denoisers run (mcdn/color.h): the light passes
    // as light, which is what sure recorded of them and what the half renders hand the
    // denoisers, whether a chain converted the frame once or this op converts a copy.
    return run_in_working_space(
        dst, src, options.aovs, "choose", [&](ImageBuf& d, const ImageBuf& s) {
            return choose_in_working_space(d, s, other, options, roi, nthreads);
        });
}

ImageBuf choose(const ImageBuf& src, const Denoiser& other, const ChooseOptions& options, ROI roi,
                int nthreads)
{
    ImageBuf dst;
    choose(dst, src, other, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
