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
void add_probe(ImageBuf& buf, const std::vector<int>& channels, const Plane probe[3], double eps)
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
bool check_finite(const ImageBuf& denoised, const ImageBuf& noisy, int nthreads, std::string& error)
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
        std::vector<float> row(size_t(spec.width) * nch),
            in(size_t(spec.width) * noisy.nchannels());
        ROI roi(spec.x, spec.x + spec.width, y, y + 1, 0, 1, 0, nch);
        denoised.get_pixels(roi, OIIO::TypeDesc::FLOAT, row.data());
        roi.chend = noisy.nchannels();
        noisy.get_pixels(roi, OIIO::TypeDesc::FLOAT, in.data());
        for (int x = 0; x < spec.width; ++x)
            for (int c = 0; c < nch; ++c) {
                float v = row[size_t(x) * nch + c];
                if (!std::isfinite(v)
                    && (source[c] < 0
                        || std::isfinite(in[size_t(x) * noisy.nchannels() + source[c]]))) {
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
                           "(a denoiser must return finite values)",
                           bad[c], spec.channelnames[c]);
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
                           "(a denoiser must return finite values)",
                           bad, spec.channel_name(channels[m]));
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
void add_count(ImageBuf& dst, const char* attribute, const ConvergedTiles& worse, const Band& band,
               int band_y)
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

// ---- the steps of one band ------------------------------------------------------------

// One channel of a band, every row.
ROI channel_roi(const ImageBuf& noisy, int channel)
{
    ROI r = noisy.roi();
    r.chbegin = channel;
    r.chend = channel + 1;
    return r;
}

// The exact bits of `channels` (read_plane would sanitize them), one plane each: of a float
// frame in memory in one pass over its pixels (a pass per channel would pull every cache
// line of the frame once per channel; the extras are 18 of Blender's channels).
std::vector<std::vector<float>> exact_bits(const ImageBuf& noisy, const std::vector<int>& channels)
{
    const size_t npixels = size_t(noisy.spec().width) * noisy.spec().height;
    std::vector<std::vector<float>> bits(channels.size(), std::vector<float>(npixels));
    if (const float* px = float_frame_pixels(noisy)) {
        const size_t n = size_t(noisy.nchannels());
        for (size_t i = 0; i < npixels; ++i)
            for (size_t m = 0; m < channels.size(); ++m)
                bits[m][i] = px[i * n + size_t(channels[m])];
        return bits;
    }
    for (size_t m = 0; m < channels.size(); ++m)
        noisy.get_pixels(channel_roi(noisy, channels[m]), OIIO::TypeDesc::FLOAT, bits[m].data());
    return bits;
}

// Exact bits as read_plane would have read them (sanitized), a plane of w x h.
Plane sanitized(const std::vector<float>& bits, int w, int h)
{
    Plane plane(w, h);
    for (size_t i = 0; i < plane.size(); ++i)
        plane.px[i] = sanitize(bits[i]);
    return plane;
}

// exact_bits' inverse, in one pass over a float frame in memory as well.
void put_back_bits(ImageBuf& noisy, const std::vector<int>& channels,
                   const std::vector<std::vector<float>>& bits)
{
    if (float* px = const_cast<float*>(float_frame_pixels(noisy))) {
        const size_t npixels = size_t(noisy.spec().width) * noisy.spec().height;
        const size_t n = size_t(noisy.nchannels());
        for (size_t i = 0; i < npixels; ++i)
            for (size_t m = 0; m < channels.size(); ++m)
                px[i * n + size_t(channels[m])] = bits[m][i];
        return;
    }
    for (size_t m = 0; m < channels.size(); ++m)
        noisy.set_pixels(channel_roi(noisy, channels[m]), OIIO::TypeDesc::FLOAT, bits[m].data());
}

/// What one band's steps share: the render x and its variance, the converged tiles, the
/// denoised y, and the divergence the probes estimate.
struct BandState {
    Plane x[3], variance[3], y[3];
    ConvergedTiles converged;
    /// The moved channels' exact bits, restored after each probe.
    std::vector<std::vector<float>> unprobed;
    /// The extras' x, exactly: put back after the denoiser in place (for its probes) and
    /// recorded, sanitized, for the mix (one copy for both: 72 bytes a pixel on Blender's
    /// six light passes).
    std::vector<std::vector<float>> extras_bits;
    /// The denoiser's own tile decisions, which hold for its probes (core/attributes.h).
    std::string denoiser_tiles;
    /// In place: noisy's spec as the denoiser left it, and the colour and extras it made
    /// (the probes see the rendered extras: an extra may be a role the denoiser reads, as
    /// Blender's DiffDir is for the CNN's split).
    ImageSpec result_spec;
    std::vector<std::vector<float>> y_bits, extras_y_bits;
    Plane divergence[3];
};

// x, its variance and the converged tiles (mcdn/skip.h: the denoiser's runs all skip the
// tiles of this map; bands start on whole tiles, so a band's map is the frame's); the
// moved channels' bits and the extras, before the denoiser, which may write them
// (SureFrame::denoise_in_place).
void read_band(BandState& st, ImageBuf& noisy, const SureOptions& options, const SureFrame& frame)
{
    read_planes(noisy,
                { { frame.color[0], &st.x[0] },
                  { frame.color[1], &st.x[1] },
                  { frame.color[2], &st.x[2] },
                  { frame.variance[0], &st.variance[0], true },
                  { frame.variance[1], &st.variance[1], true },
                  { frame.variance[2], &st.variance[2], true } },
                {}, frame.nthreads);
    st.converged = converged_tiles_of(noisy, st.x, st.variance, options.skip);
    if (options.skip.enabled)
        noisy.specmod().attribute(kConvergedAttribute, encode_converged_tiles(st.converged));
    if (frame.eps > 0 || frame.denoise_in_place)
        st.unprobed = exact_bits(noisy, frame.moved);
    st.extras_bits = exact_bits(noisy, frame.extras);
}

// y = F(x) made in noisy itself, which becomes dst once the probes are done; the probes
// then see the input as it was (x and its spec; the extras they do not read).
bool denoise_in_place(BandState& st, ImageBuf& noisy, const Denoiser& denoiser,
                      const SureFrame& frame, StageTrace& trace, std::string& error)
{
    const ImageSpec unprobed_spec = noisy.spec();
    const std::vector<std::vector<float>>& extras_bits = st.extras_bits;
    if (!denoiser(noisy, noisy)) {
        error = format("sure: the denoiser failed: {}", noisy.geterror());
        return false;
    }
    trace.mark("y = F(x)");
    st.y_bits = exact_bits(noisy, frame.color);
    st.extras_y_bits = exact_bits(noisy, frame.extras);
    if (!check_finite_in_place(noisy.spec(), frame.color, st.y_bits,
                               { st.unprobed.begin(), st.unprobed.begin() + 3 }, error)
        || !check_finite_in_place(noisy.spec(), frame.extras, st.extras_y_bits, extras_bits, error))
        return false;
    put_back_bits(noisy, frame.extras, extras_bits);
    for (int c = 0; c < 3; ++c)
        st.y[c] = sanitized(st.y_bits[size_t(c)], st.x[c].width, st.x[c].height);
    st.result_spec = noisy.spec();
    st.result_spec.erase_attribute(kOutputRoomAttribute);
    st.result_spec.erase_attribute(kConvergedAttribute);
    st.result_spec.erase_attribute(kDenoiserTilesAttribute);
    st.denoiser_tiles = noisy.spec().get_string_attribute(kDenoiserTilesAttribute);
    noisy.specmod() = unprobed_spec;
    noisy.specmod().erase_attribute(kOutputRoomAttribute);
    put_back_bits(noisy, { frame.color[0], frame.color[1], frame.color[2] },
                  { st.unprobed.begin(), st.unprobed.begin() + 3 });
    trace.mark("y is finite, x put back");
    return true;
}

// y = F(x) into a buffer of its own, written to dst at once, its colour kept.
bool denoise_into_output(BandState& st, ImageBuf& dst, ImageBuf& noisy, const Band& band,
                         const Denoiser& denoiser, const SureFrame& frame, StageTrace& trace,
                         std::string& error)
{
    ImageBuf denoised;
    const bool ran = denoiser(denoised, noisy);
    noisy.specmod().erase_attribute(kOutputRoomAttribute);     // for this run only
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
    read_planes(denoised,
                { { frame.color[0], &st.y[0] },
                  { frame.color[1], &st.y[1] },
                  { frame.color[2], &st.y[2] } },
                {}, frame.nthreads);
    st.denoiser_tiles = denoised.spec().get_string_attribute(kDenoiserTilesAttribute);
    if (!dst.initialized() && is_whole_output(denoised, band, frame)) {
        // What allocate_output and write_denoised_rows would make of it.
        dst = std::move(denoised);
        dst.specmod().erase_attribute(kConvergedAttribute);
        dst.specmod().erase_attribute(kDenoiserTilesAttribute);
    } else if (!write_denoised_rows(dst, denoised, band, frame, error)) {
        return false;
    }
    trace.mark("y into the output");
    return true;
}

// Eq. 2: probe with b ~ N(0, Sigma) K times; the render and both halves move together. b of
// a pixel is drawn by its index in the frame, so every band sees the same probe there. No
// probe on the tiles the denoiser passed through (`passed`).
bool probe_divergence(BandState& st, ImageBuf& noisy, const Denoiser& denoiser,
                      const SureOptions& options, const SureFrame& frame,
                      const ConvergedTiles& passed, StageTrace& trace, std::string& error)
{
    const int w = st.x[0].width, h = st.x[0].height;
    const Plane no_probe(w, h);
    const uint64_t first_index = uint64_t(noisy.spec().y - frame.index_origin) * uint64_t(w);
    const double eps = frame.eps;
    for (int c = 0; c < 3; ++c)
        st.divergence[c] = Plane(w, h);
    for (int k = 0; eps > 0 && k < options.probes; ++k) {
        Plane b[3];
        for (int c = 0; c < 3; ++c)
            b[c] = Plane(w, h);
        parallel_for_index(h, frame.nthreads, [&](int row) {
            for (int c = 0; c < 3; ++c)
                for (size_t i = size_t(row) * w; i < size_t(row + 1) * w; ++i)
                    b[c].px[i] =
                        std::sqrt(st.variance[c].px[i])
                        * standard_normal(options.seed, uint64_t(k), (first_index + i) * 3 + c);
        });
        for (int c = 0; c < 3; ++c)
            pass_through_converged(b[c], no_probe, passed);
        // Probed in place and restored after (a copy of every channel per probe would cost
        // as much as the denoiser's own work on half-converged frames).
        noisy.specmod().attribute(kProbeAttribute, 1);
        noisy.specmod().attribute(kColorOnlyAttribute, 1);
        if (!st.denoiser_tiles.empty())
            noisy.specmod().attribute(kDenoiserTilesAttribute, st.denoiser_tiles);
        for (size_t g = 0; g < frame.moved.size(); g += 3)
            add_probe(noisy, { frame.moved[g], frame.moved[g + 1], frame.moved[g + 2] }, b, eps);
        trace.mark("probe b");
        ImageBuf response;
        const bool probe_ok = denoiser(response, noisy);
        trace.mark("F(x + eps b)");
        put_back_bits(noisy, frame.moved, st.unprobed);
        noisy.specmod().erase_attribute(kProbeAttribute);
        noisy.specmod().erase_attribute(kColorOnlyAttribute);
        noisy.specmod().erase_attribute(kDenoiserTilesAttribute);
        if (!probe_ok) {
            error = format("sure: the denoiser failed on probe {}: {}", k, response.geterror());
            return false;
        }
        for (int c = 0; c < 3; ++c) {
            const std::string& name = noisy.spec().channel_name(frame.color[c]);
            const int index = response.spec().channelindex(name);
            if (index < 0) {
                error =
                    format("sure: the denoiser's result on probe {} has no channel '{}'", k, name);
                return false;
            }
            Plane f = read_plane(response, index);
            for (size_t i = 0; i < f.size(); ++i)
                st.divergence[c].px[i] +=
                    float(b[c].px[i] * (double(f.px[i]) - st.y[c].px[i]) / (eps * options.probes));
        }
    }
    return true;
}

// Eq. 1 per pixel and channel (d = 1): SURE = (y - x)^2 + 2 sigma^2 f'(x) - sigma^2; the
// safety net (skip/worse_tiles.h: where SURE says y is worse than x, y = x and SURE is the
// render's own error, as on a tile passed through); all of sure's channels in one pass over
// the output's rows (and, where the net fell back, the colour and the extras).
void write_sure(BandState& st, ImageBuf& dst, const ImageSpec& in_spec, const Band& band,
                int band_y, const SureOptions& options, const SureFrame& frame,
                const ConvergedTiles& passed)
{
    const int w = st.x[0].width, h = st.x[0].height;
    for (int c = 0; c < 3; ++c)  // the pass-through's f'(x) = 1
        pass_through_converged(st.divergence[c], st.variance[c], passed);
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
                double d = double(st.y[c].px[i]) - st.x[c].px[i];
                residual[c].px[i] = sanitize(float(d * d));
                st.divergence[c].px[i] = sanitize(st.divergence[c].px[i]);
                estimate[c].px[i] =
                    sanitize(residual[c].px[i] + 2 * st.divergence[c].px[i] - st.variance[c].px[i]);
            }
        });
    }
    const ConvergedTiles worse = tiles_worse_than_render(estimate, st.variance, st.y, passed);
    const Plane fell_back = frame.fallback_channel ? tile_flags(worse, w, h) : Plane();
    add_count(dst, options.fallback ? kSureFallbackCountAttribute : kSureWorseCountAttribute, worse,
              band, band_y);
    const bool fall_back = options.fallback && worse.any();
    if (fall_back) {
        const Plane zero(w, h);
        for (int c = 0; c < 3; ++c) {
            pass_through_converged(st.y[c], st.x[c], worse);
            pass_through_converged(estimate[c], st.variance[c], worse);
            pass_through_converged(st.divergence[c], st.variance[c], worse);
            pass_through_converged(residual[c], zero, worse);
        }
    }
    std::vector<const Plane*> planes;
    for (const Plane* group : { st.x, estimate, st.divergence, residual })
        for (int c = 0; c < 3; ++c)
            planes.push_back(&group[c]);
    std::vector<Plane> extras;
    for (const std::vector<float>& bits : st.extras_bits)
        extras.push_back(sanitized(bits, w, h));
    for (const Plane& e : extras)
        planes.push_back(&e);
    if (frame.fallback_channel)
        planes.push_back(&fell_back);
    if (fall_back) {
        for (int c = 0; c < 3; ++c) {
            out.push_back(dst.spec().channelindex(in_spec.channel_name(frame.color[c])));
            planes.push_back(&st.y[c]);
        }
        for (size_t e = 0; e < frame.extras.size(); ++e) {
            out.push_back(dst.spec().channelindex(in_spec.channel_name(frame.extras[e])));
            planes.push_back(&extras[e]);
        }
    }
    write_rows(dst, out, planes, band_y, where);
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
    BandState st;
    read_band(st, noisy, options, frame);
    trace.mark("read x, converged tiles");
    if (!(frame.denoise_in_place
              ? denoise_in_place(st, noisy, denoiser, frame, trace, error)
              : denoise_into_output(st, dst, noisy, band, denoiser, frame, trace, error)))
        return false;
    // Of those, the tiles the denoiser did pass through (a callable may not skip): no probes.
    const ConvergedTiles passed = tiles_where_equal(st.y, st.x, &st.converged);
    if (!probe_divergence(st, noisy, denoiser, options, frame, passed, trace, error))
        return false;
    const int band_y = noisy.spec().y;
    // In place, noisy is the result now: y and the spec the denoiser gave it.
    if (frame.denoise_in_place) {
        put_back_bits(noisy, frame.color, st.y_bits);
        put_back_bits(noisy, frame.extras, st.extras_y_bits);
        noisy.specmod() = st.result_spec;
        dst = std::move(noisy);
    }
    write_sure(st, dst, frame.denoise_in_place ? dst.spec() : noisy.spec(), band, band_y, options,
               frame, passed);
    trace.mark("eq. 1, sure.* channels");
    return true;
}

}  // namespace mcdn
