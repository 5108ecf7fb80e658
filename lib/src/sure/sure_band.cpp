// One band of Monte-Carlo SURE (PD §2.3 eq. 1, §3.2 eq. 2; sure_steps.h): denoise once,
// probe K times, assemble SURE per pixel and channel, write the band's own rows.
#include <cmath>

#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "core/random.h"
#include "core/trace.h"
#include "skip/converged_tiles.h"
#include "skip/worse_tiles.h"
#include "sure/sure_steps.h"

namespace mcdn {

namespace {

using OIIO::Strutil::fmt::format;

// dst for the frame: the denoiser's channels (its first band's spec), then sure's own
// (an existing one of the same name is reused, as add_channels does). Zero-filled only when
// sure's channels are not written everywhere (they are zero outside `where`): the bands
// write every row of the rest.
bool allocate_output(ImageBuf& dst, const ImageSpec& denoised, const SureFrame& frame)
{
    ImageSpec spec = denoised;
    spec.set_format(OIIO::TypeDesc::FLOAT);
    spec.y = frame.whole.ybegin;
    spec.height = frame.whole.height();
    spec.erase_attribute(kConvergedAttribute);
    spec.erase_attribute(kDenoiserTilesAttribute);
    for (const std::string& name : sure_channel_names(frame))
        if (spec.channelindex(name) < 0) {
            spec.channelnames.push_back(name);
            ++spec.nchannels;
        }
    const ROI& w = frame.where;
    const bool written_everywhere = w.xbegin <= frame.whole.xbegin && w.xend >= frame.whole.xend
                                    && w.ybegin <= frame.whole.ybegin && w.yend >= frame.whole.yend;
    return allocate_frame(dst, spec, !written_everywhere);
}

// The denoised band's own rows, every channel, into the leading channels of dst.
bool write_denoised_rows(ImageBuf& dst, const ImageBuf& denoised, const Band& band,
                         const SureFrame& frame, std::string& error)
{
    if (!dst.initialized() && !allocate_output(dst, denoised.spec(), frame)) {
        error = "sure: " + dst.geterror();
        return false;
    }
    const ImageSpec& spec = denoised.spec();
    const std::vector<std::string>& names = dst.spec().channelnames;
    if (spec.x != frame.whole.xbegin || spec.width != frame.whole.width()
        || spec.y != band.cut.ybegin || spec.height != band.cut.height()
        || spec.nchannels > dst.nchannels()
        || !std::equal(spec.channelnames.begin(), spec.channelnames.end(), names.begin())) {
        error = format("sure: the denoiser's result ({}x{} at y={}, {} channels) does not match "
                       "its input ({}x{} at y={}) or its result on the band above",
                       spec.width, spec.height, spec.y, spec.nchannels, frame.whole.width(),
                       band.cut.height(), band.cut.ybegin);
        return false;
    }
    ROI rows = frame.whole;
    rows.ybegin = band.own_begin;
    rows.yend = band.own_end;
    rows.chbegin = 0;
    rows.chend = spec.nchannels;
    // Straight into dst's pixels, with dst's strides: no band-sized copy on the way.
    if (!denoised.get_pixels(rows, OIIO::TypeDesc::FLOAT, dst.pixeladdr(rows.xbegin, rows.ybegin),
                             dst.pixel_stride(), dst.scanline_stride())) {
        error = format("sure: could not read the denoiser's result: {}", denoised.geterror());
        return false;
    }
    return true;
}

// Adds eps*b to the given channels of `buf` (b is one probe, one plane per colour channel).
void add_probe(ImageBuf& buf, const std::vector<int>& channels, const Plane probe[3],
               double eps)
{
    for (int c = 0; c < 3; ++c) {
        Plane plane = read_plane(buf, channels[c]);
        for (size_t i = 0; i < plane.size(); ++i)
            plane.px[i] += float(eps * probe[c].px[i]);
        write_plane(buf, channels[c], plane, buf.roi());
    }
}

// A denoiser (a Python or C++ callable) must not make NaN or Inf: a value that is not
// finite where its input's same channel was is an error (a pass-through channel's own NaN
// is the input's, which -o reports).
bool check_finite(const ImageBuf& denoised, const ImageBuf& noisy, int nthreads,
                  std::string& error)
{
    const ImageSpec& spec = denoised.spec();
    const int nch = spec.nchannels;
    std::vector<int> source(nch);
    for (int c = 0; c < nch; ++c)
        source[c] = noisy.spec().channelindex(spec.channelnames[c]);
    // Rows in parallel, each counting into its own slot (the sums do not depend on the order).
    std::vector<std::vector<uint32_t>> row_bad(spec.height);
    parallel_for_index(spec.height, nthreads, [&](int r) {
        const int y = spec.y + r;
        std::vector<float> row(size_t(spec.width) * nch), in(size_t(spec.width) * noisy.nchannels());
        ROI roi(spec.x, spec.x + spec.width, y, y + 1, 0, 1, 0, nch);
        denoised.get_pixels(roi, OIIO::TypeDesc::FLOAT, row.data());
        roi.chend = noisy.nchannels();
        noisy.get_pixels(roi, OIIO::TypeDesc::FLOAT, in.data());
        for (int x = 0; x < spec.width; ++x)
            for (int c = 0; c < nch; ++c) {
                float v = row[size_t(x) * nch + c];
                if (!std::isfinite(v)
                    && (source[c] < 0 || std::isfinite(in[size_t(x) * noisy.nchannels() + source[c]]))) {
                    row_bad[r].resize(nch, 0);
                    ++row_bad[r][c];
                }
            }
    });
    std::vector<size_t> bad(nch, 0);
    for (const auto& counts : row_bad)
        for (size_t c = 0; c < counts.size(); ++c)
            bad[c] += counts[c];
    for (int c = 0; c < spec.nchannels; ++c)
        if (bad[c]) {
            error = format("sure: the denoiser returned {} NaN or Inf values in channel {} "
                           "(a denoiser must return finite values)", bad[c],
                           spec.channelnames[c]);
            return false;
        }
    return true;
}

// check_finite for a denoiser that ran in place: `now`, the bits of `channels` of `spec`'s
// frame after it, against `before` (one plane each).
bool check_finite_in_place(const ImageSpec& spec, const std::vector<int>& channels,
                           const std::vector<std::vector<float>>& now,
                           const std::vector<std::vector<float>>& before, std::string& error)
{
    for (size_t m = 0; m < channels.size(); ++m) {
        size_t bad = 0;
        for (size_t i = 0; i < now[m].size(); ++i)
            bad += !std::isfinite(now[m][i]) && std::isfinite(before[m][i]);
        if (bad) {
            error = format("sure: the denoiser returned {} NaN or Inf values in channel {} "
                           "(a denoiser must return finite values)", bad,
                           spec.channel_name(channels[m]));
            return false;
        }
    }
    return true;
}

// The denoiser's result is the output as it stands: the band is the whole frame, and the
// result is a float frame in memory on the frame's window that kept sure's channels.
bool is_whole_output(const ImageBuf& denoised, const Band& band, const SureFrame& frame)
{
    const ImageSpec& spec = denoised.spec();
    if (band.cut.ybegin != frame.whole.ybegin || band.cut.yend != frame.whole.yend
        || band.own_begin != frame.whole.ybegin || band.own_end != frame.whole.yend
        || !float_frame_pixels(denoised) || spec.x != frame.whole.xbegin
        || spec.width != frame.whole.width() || spec.y != frame.whole.ybegin
        || spec.height != frame.whole.height())
        return false;
    for (const std::string& name : sure_channel_names(frame))
        if (spec.channelindex(name) < 0)
            return false;
    return true;
}

// Adds the tiles of `worse` that start in the band's own rows to dst's int `attribute`.
void add_count(ImageBuf& dst, const char* attribute, const ConvergedTiles& worse,
               const Band& band, int band_y)
{
    if (!worse.any())
        return;
    int count = 0;
    for (int ty = 0; ty < worse.tiles_y; ++ty) {
        const int top = band_y + ty * kConvergedTileSize;
        if (top >= band.own_begin && top < band.own_end)
            for (int tx = 0; tx < worse.tiles_x; ++tx)
                count += worse.tile(tx, ty) ? 1 : 0;
    }
    if (count > 0)
        dst.specmod().attribute(attribute, dst.spec().get_int_attribute(attribute, 0) + count);
}

}  // namespace

std::vector<std::string> sure_channel_names(const SureFrame& frame)
{
    std::vector<std::string> names;
    for (const auto* group : { sure_channels::kNoisy, sure_channels::kSure,
                               sure_channels::kDivergence, sure_channels::kResidual })
        names.insert(names.end(), group, group + 3);
    for (const std::string& name : frame.extra_names)
        names.push_back(sure_channels::noisy_extra(name));
    if (frame.fallback_channel)
        names.push_back(sure_channels::kFallback);
    return names;
}

void add_extras(SureFrame& frame, const AovSet& aovs)
{
    for (const AovSet::Extra& extra : aovs.extras())
        if (extra.channels.size() == 3) {
            frame.extras.insert(frame.extras.end(), extra.channels.begin(), extra.channels.end());
            frame.extra_names.insert(frame.extra_names.end(), extra.names.begin(),
                                     extra.names.end());
        }
}

std::vector<std::string> sure_channel_names(const AovSet& aovs, const SureOptions& options)
{
    SureFrame frame;
    add_extras(frame, aovs);
    frame.fallback_channel = options.output_fallback;
    return sure_channel_names(frame);
}

bool sure_band(ImageBuf& dst, ImageBuf& noisy, const Band& band, const Denoiser& denoiser,
               const SureOptions& options, const SureFrame& frame, std::string& error)
{
    StageTrace trace("sure");
    Plane x[3], variance[3];
    read_planes(noisy, { { frame.color[0], &x[0] }, { frame.color[1], &x[1] },
                         { frame.color[2], &x[2] }, { frame.variance[0], &variance[0], true },
                         { frame.variance[1], &variance[1], true },
                         { frame.variance[2], &variance[2], true } },
                {}, frame.nthreads);

    // mcdn/skip.h: the denoiser's runs all skip the tiles of this map (bands start on whole
    // tiles, so a band's map is the frame's).
    const ConvergedTiles converged = converged_tiles_of(noisy, x, variance, options.skip);
    if (options.skip.enabled)
        noisy.specmod().attribute(kConvergedAttribute, encode_converged_tiles(converged));

    // The moved channels' exact bits (read_plane would sanitize), restored after each probe;
    // the extras' x, recorded for the mix. Both before the denoiser, which may write them
    // (SureFrame::denoise_in_place).
    const int w = x[0].width, h = x[0].height;
    auto channel_roi = [&](int channel) {
        ROI r = noisy.roi();
        r.chbegin = channel;
        r.chend = channel + 1;
        return r;
    };
    auto exact = [&](const std::vector<int>& channels) {
        std::vector<std::vector<float>> bits(channels.size());
        for (size_t m = 0; m < channels.size(); ++m) {
            bits[m].resize(size_t(w) * h);
            noisy.get_pixels(channel_roi(channels[m]), OIIO::TypeDesc::FLOAT, bits[m].data());
        }
        return bits;
    };
    auto put_back = [&](const std::vector<int>& channels,
                        const std::vector<std::vector<float>>& bits) {
        for (size_t m = 0; m < channels.size(); ++m)
            noisy.set_pixels(channel_roi(channels[m]), OIIO::TypeDesc::FLOAT, bits[m].data());
    };
    const std::vector<std::vector<float>> unprobed = frame.eps > 0 || frame.denoise_in_place
                                                         ? exact(frame.moved)
                                                         : std::vector<std::vector<float>>();
    std::vector<Plane> extras(frame.extras.size());
    {
        std::vector<PlaneRead> reads;
        for (size_t e = 0; e < frame.extras.size(); ++e)
            reads.push_back({ frame.extras[e], &extras[e] });
        read_planes(noisy, reads, {}, frame.nthreads);
    }

    // y = F(x): the result we report SURE for. Written to dst at once, its colour kept; in
    // place, made in noisy itself, which becomes dst once the probes are done.
    Plane y[3];
    std::string denoiser_tiles;
    ImageSpec result_spec;                 // in place: noisy's spec as the denoiser left it
    std::vector<std::vector<float>> y_bits;  // in place: the colour as the denoiser made it
    if (frame.denoise_in_place) {
        trace.mark("read x, converged tiles");
        const ImageSpec unprobed_spec = noisy.spec();
        const std::vector<std::vector<float>> extras_bits = exact(frame.extras);
        if (!denoiser(noisy, noisy)) {
            error = format("sure: the denoiser failed: {}", noisy.geterror());
            return false;
        }
        trace.mark("y = F(x)");
        y_bits = exact(frame.color);
        if (!check_finite_in_place(noisy.spec(), frame.color, y_bits,
                                   { unprobed.begin(), unprobed.begin() + 3 }, error)
            || !check_finite_in_place(noisy.spec(), frame.extras, exact(frame.extras),
                                      extras_bits, error))
            return false;
        for (int c = 0; c < 3; ++c) {  // as read_plane reads them
            y[c] = Plane(w, h);
            for (size_t i = 0; i < y[c].size(); ++i)
                y[c].px[i] = sanitize(y_bits[c][i]);
        }
        result_spec = noisy.spec();
        result_spec.erase_attribute(kOutputRoomAttribute);
        result_spec.erase_attribute(kConvergedAttribute);
        result_spec.erase_attribute(kDenoiserTilesAttribute);
        denoiser_tiles = noisy.spec().get_string_attribute(kDenoiserTilesAttribute);
        // The probes see the input as it was: x and its spec (the extras they do not read).
        noisy.specmod() = unprobed_spec;
        noisy.specmod().erase_attribute(kOutputRoomAttribute);
        put_back({ frame.color[0], frame.color[1], frame.color[2] },
                 { unprobed.begin(), unprobed.begin() + 3 });
        trace.mark("y is finite, x put back");
    } else {
        ImageBuf denoised;
        trace.mark("read x, converged tiles");
        const bool ran = denoiser(denoised, noisy);
        noisy.specmod().erase_attribute(kOutputRoomAttribute);  // for this run only
        denoised.specmod().erase_attribute(kOutputRoomAttribute);  // a callable's copy of it
        if (!ran) {
            error = format("sure: the denoiser failed: {}", denoised.geterror());
            return false;
        }
        trace.mark("y = F(x)");
        // Its channels become the output's: a NaN there would leave the op.
        if (!check_finite(denoised, noisy, frame.nthreads, error))
            return false;
        trace.mark("y is finite");
        read_planes(denoised, { { frame.color[0], &y[0] }, { frame.color[1], &y[1] },
                                { frame.color[2], &y[2] } },
                    {}, frame.nthreads);
        // The denoiser's own tile decisions hold for its probes (core/attributes.h).
        denoiser_tiles = denoised.spec().get_string_attribute(kDenoiserTilesAttribute);
        if (!dst.initialized() && is_whole_output(denoised, band, frame)) {
            // What allocate_output and write_denoised_rows would make of it.
            dst = std::move(denoised);
            dst.specmod().erase_attribute(kConvergedAttribute);
            dst.specmod().erase_attribute(kDenoiserTilesAttribute);
        } else if (!write_denoised_rows(dst, denoised, band, frame, error)) {
            return false;
        }
        trace.mark("y into the output");
    }
    // Of those, the tiles the denoiser did pass through (a callable may not skip): no probes.
    const ConvergedTiles passed = tiles_where_equal(y, x, &converged);
    const Plane no_probe(w, h);

    // Eq. 2: probe with b ~ N(0, Sigma); the render and both halves move together. b of a
    // pixel is drawn by its index in the frame, so every band sees the same probe there.
    const uint64_t first_index = uint64_t(noisy.spec().y - frame.index_origin) * uint64_t(w);
    const double eps = frame.eps;
    Plane divergence[3] = { Plane(w, h), Plane(w, h), Plane(w, h) };
    for (int k = 0; eps > 0 && k < options.probes; ++k) {
        Plane b[3];
        for (int c = 0; c < 3; ++c)
            b[c] = Plane(w, h);
        parallel_for_index(h, frame.nthreads, [&](int row) {
            for (int c = 0; c < 3; ++c)
                for (size_t i = size_t(row) * w; i < size_t(row + 1) * w; ++i)
                    b[c].px[i] = std::sqrt(variance[c].px[i])
                                 * standard_normal(options.seed, uint64_t(k),
                                                   (first_index + i) * 3 + c);
        });
        for (int c = 0; c < 3; ++c)
            pass_through_converged(b[c], no_probe, passed);
        // Probed in place and restored after (a copy of every channel per probe would cost
        // as much as the denoiser's own work on half-converged frames).
        noisy.specmod().attribute(kProbeAttribute, 1);
        noisy.specmod().attribute(kColourOnlyAttribute, 1);
        if (!denoiser_tiles.empty())
            noisy.specmod().attribute(kDenoiserTilesAttribute, denoiser_tiles);
        for (size_t g = 0; g < frame.moved.size(); g += 3)
            add_probe(noisy, { frame.moved[g], frame.moved[g + 1], frame.moved[g + 2] }, b, eps);
        trace.mark("probe b");
        ImageBuf response;
        const bool probe_ok = denoiser(response, noisy);
        trace.mark("F(x + eps b)");
        put_back(frame.moved, unprobed);
        noisy.specmod().erase_attribute(kProbeAttribute);
        noisy.specmod().erase_attribute(kColourOnlyAttribute);
        noisy.specmod().erase_attribute(kDenoiserTilesAttribute);
        if (!probe_ok) {
            error = format("sure: the denoiser failed on probe {}: {}", k, response.geterror());
            return false;
        }
        for (int c = 0; c < 3; ++c) {
            const std::string& name = noisy.spec().channel_name(frame.color[c]);
            const int index = response.spec().channelindex(name);
            if (index < 0) {
                error = format("sure: the denoiser's result on probe {} has no channel '{}'", k,
                               name);
                return false;
            }
            Plane f = read_plane(response, index);
            for (size_t i = 0; i < f.size(); ++i)
                divergence[c].px[i] += float(b[c].px[i] * (double(f.px[i]) - y[c].px[i])
                                             / (eps * options.probes));
        }
    }

    const int band_y = noisy.spec().y;
    // In place, noisy is the result now: y and the spec the denoiser gave it.
    if (frame.denoise_in_place) {
        put_back(frame.color, y_bits);
        noisy.specmod() = result_spec;
        dst = std::move(noisy);
    }
    const ImageSpec& in_spec = frame.denoise_in_place ? dst.spec() : noisy.spec();

    // Eq. 1 per pixel and channel (d = 1): SURE = (y - x)^2 + 2 sigma^2 f'(x) - sigma^2.
    for (int c = 0; c < 3; ++c)  // the pass-through's f'(x) = 1
        pass_through_converged(divergence[c], variance[c], passed);
    const std::vector<std::string> names = sure_channel_names(frame);
    std::vector<int> out;
    for (const std::string& name : names)
        out.push_back(dst.spec().channelindex(name));
    ROI where = frame.where;
    where.ybegin = std::max(where.ybegin, band.own_begin);
    where.yend = std::min(where.yend, band.own_end);
    Plane residual[3], estimate[3];
    for (int c = 0; c < 3; ++c) {
        residual[c] = Plane(w, h);
        estimate[c] = Plane(w, h);
        parallel_for_index(h, frame.nthreads, [&](int row) {
            for (size_t i = size_t(row) * w; i < size_t(row + 1) * w; ++i) {
                double d = double(y[c].px[i]) - x[c].px[i];
                residual[c].px[i] = sanitize(float(d * d));
                divergence[c].px[i] = sanitize(divergence[c].px[i]);
                estimate[c].px[i] = sanitize(residual[c].px[i] + 2 * divergence[c].px[i]
                                             - variance[c].px[i]);
            }
        });
    }

    // The safety net (skip/worse_tiles.h): where SURE says y is worse than x, y = x and SURE
    // is the render's own error, as on a tile passed through.
    const ConvergedTiles worse = tiles_worse_than_render(estimate, variance, y, passed);
    const Plane fell_back = frame.fallback_channel ? tile_flags(worse, w, h) : Plane();
    add_count(dst, options.fallback ? kSureFallbackCountAttribute : kSureWorseCountAttribute,
              worse, band, band_y);
    const bool fall_back = options.fallback && worse.any();
    if (fall_back) {
        const Plane zero(w, h);
        for (int c = 0; c < 3; ++c) {
            pass_through_converged(y[c], x[c], worse);
            pass_through_converged(estimate[c], variance[c], worse);
            pass_through_converged(divergence[c], variance[c], worse);
            pass_through_converged(residual[c], zero, worse);
        }
    }

    // All of sure's channels in one pass over the output's rows (and, where the net fell
    // back, the colour and the extras).
    std::vector<const Plane*> planes;
    for (const Plane* group : { x, estimate, divergence, residual })
        for (int c = 0; c < 3; ++c)
            planes.push_back(&group[c]);
    for (const Plane& e : extras)
        planes.push_back(&e);
    if (frame.fallback_channel)
        planes.push_back(&fell_back);
    if (fall_back) {
        for (int c = 0; c < 3; ++c) {
            out.push_back(dst.spec().channelindex(in_spec.channel_name(frame.color[c])));
            planes.push_back(&y[c]);
        }
        for (size_t e = 0; e < frame.extras.size(); ++e) {
            out.push_back(dst.spec().channelindex(in_spec.channel_name(frame.extras[e])));
            planes.push_back(&extras[e]);
        }
    }
    write_rows(dst, out, planes, band_y, where);
    trace.mark("eq. 1, sure.* channels");
    return true;
}

}  // namespace mcdn
