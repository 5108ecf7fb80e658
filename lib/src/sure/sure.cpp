// Monte-Carlo SURE of a denoiser (PD §2.3 eq. 1, §3.2 eq. 2). Reads top to bottom: check the
// inputs, fix what the whole frame decides (the probe step, the channels), then run the
// denoiser and its probes band by band (sure_band.cpp; one band unless the frame is large).
#include "mcdn/sure.h"

#include <cmath>

#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/channels.h"
#include "core/frame_facts.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "core/progress.h"
#include "core/trace.h"
#include "mcdn/color.h"
#include "sure/sure_steps.h"

namespace mcdn {

namespace {

// `probed`: src itself, mutable (sure_probing_src), or null: the copy of a band is probed.
bool sure_in_working_space(ImageBuf& dst, const ImageBuf& src, const Denoiser& denoiser,
                           const SureOptions& options, ROI roi, int nthreads, ImageBuf* probed)
{
    AovSet aovs;
    std::string error;
    if (!check_op_input(src, options.aovs, aovs, "sure", error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    if (!aovs.require({ Role::Color, Role::ColorVariance }, src.spec(), error)) {
        dst.errorfmt("sure: {}", error);
        return false;
    }
    if (!denoiser || options.probes < 1) {
        dst.errorfmt("sure: needs a denoiser and at least one probe (probes={})", options.probes);
        return false;
    }
    // eps = 0 would make every divergence 0 (and SURE the residual alone).
    if (!(options.epsilon_relative > 0 && options.epsilon_relative <= kMaxEpsilonRelative)) {
        dst.errorfmt("sure: eps={} must be above 0 and at most {} (a step relative to the "
                     "image's mean |x|)",
                     options.epsilon_relative, kMaxEpsilonRelative);
        return false;
    }
    SureFrame frame;
    frame.whole = src.roi();
    frame.where = output_roi(src, roi);
    frame.color = aovs.channels(Role::Color);
    frame.variance = aovs.channels(Role::ColorVariance);
    frame.moved = frame.color;
    for (Role half : { Role::ColorA, Role::ColorB })
        if (aovs.has(half))
            frame.moved.insert(frame.moved.end(), aovs.channels(half).begin(),
                               aovs.channels(half).end());
    add_extras(frame, aovs);
    // The frame's facts: a chain band's own, else the frame's colour sums, handed to the
    // denoiser on each of its inputs (core/frame_facts.h): every run, probed or not, then
    // takes the same unprobed frame's statistics.
    FrameFacts facts;
    const bool band_of_frame = frame_facts(facts, src.spec());
    if (!band_of_frame) {
        facts.ybegin = frame.whole.ybegin;
        facts.yend = frame.whole.yend;
        facts.color = color_sums(src, frame.color.data(), frame.variance.data());
        // The unprobed exposure too (OIDN's networks read it): every probe the same.
        facts.has_exposure = true;
        facts.exposure = autoexposure(src, frame.color.data());
    }
    frame.index_origin = facts.ybegin;
    // eps such that eps * mean(sqrt(Var)) = epsilon_relative * mean|x| over the frame.
    frame.eps = relative_probe_step(facts.color, options.epsilon_relative);
    frame.fallback_channel = options.output_fallback;
    frame.nthreads = nthreads;
    StageTrace trace("sure");

    // Bands only when the denoiser says how far it reaches (SureOptions::denoiser_radius).
    const std::vector<Band> bands =
        options.denoiser_radius >= 0
            ? plan_bands(frame.whole, options.denoiser_radius,
                         is_frame_band(src.spec()) ? 0 : options.band_pixels)
            : plan_bands(frame.whole, 0, 0);
    ImageBuf out;
    ProgressCounter progress(options.progress, "sure", int(bands.size()));
    // One band of a float frame in memory that is the caller's to probe: probed as it is
    // (its spec and its probed channels' bits put back after), the denoiser's copy of it
    // given the room for sure's channels (core/attributes.h): a frame-sized copy less.
    const bool in_place = probed && bands.size() == 1 && float_frame_pixels(*probed);
    struct SpecBack {
        ImageBuf* buf;
        ImageSpec spec;
        ~SpecBack()
        {
            if (buf)
                buf->specmod() = spec;
        }
    } spec_back { in_place ? probed : nullptr, in_place ? probed->spec() : ImageSpec() };
    for (const Band& band : bands) {
        // The band's rows, with room for sure's channels (sure_steps.h).
        ImageBuf copy;
        if (in_place) {
            std::vector<std::string> room;
            for (const std::string& name : sure_channel_names(frame))
                if (src.spec().channelindex(name) < 0)
                    room.push_back(name);
            if (!room.empty())
                probed->specmod().attribute(kOutputRoomAttribute, OIIO::Strutil::join(room, "\n"));
            // With the room there already, the denoiser runs in probed and probed is the
            // result (its spec is the result's then, not put back).
            frame.denoise_in_place = room.empty() && options.denoiser_in_place;
            if (frame.denoise_in_place)
                spec_back.buf = nullptr;
        } else {
            copy = copy_with_channels(src, sure_channel_names(frame), band.cut, nthreads);
            if (!copy.localpixels())
                return dst.errorfmt("sure: out of memory for a {}x{} frame of {} channels",
                                    copy.spec().width, copy.spec().height, copy.spec().nchannels),
                       false;
        }
        ImageBuf& noisy = in_place ? *probed : copy;
        if (!band_of_frame)
            set_frame_facts(noisy.specmod(), facts);
        if (!sure_band(out, noisy, band, denoiser, options, frame, error)) {
            dst.errorfmt("{}", error);
            return false;
        }
        trace.mark("band: denoiser, probe, eq. 7");
        if (!progress.advance()) {
            dst.errorfmt("{}", progress.error());
            return false;
        }
    }
    if (!band_of_frame)
        out.specmod().erase_attribute(kFrameFactsAttribute);
    if (options.output_fallback)  // asked for, so written (core/channels.h)
        add_channels(out, { sure_channels::kFallback });
    dst = std::move(out);
    return true;
}

}  // namespace

bool sure(ImageBuf& dst, const ImageBuf& src, const Denoiser& denoiser, const SureOptions& options,
          ROI roi, int nthreads)
{
    // The denoiser runs on its own threads; sure's loops are light.
    if (!check_op_threads(dst, nthreads, "sure"))
        return false;
    return run_in_working_space(
        dst, src, options.aovs, "sure", [&](ImageBuf& d, const ImageBuf& s) {
            return sure_in_working_space(d, s, denoiser, options, roi, nthreads, nullptr);
        });
}

bool sure_probing_src(ImageBuf& dst, ImageBuf& src, const Denoiser& denoiser,
                      const SureOptions& options, ROI roi, int nthreads)
{
    if (!check_op_threads(dst, nthreads, "sure"))
        return false;
    // src itself only where the op runs on it (not on a copy in the working space).
    return run_in_working_space(
        dst, src, options.aovs, "sure", [&](ImageBuf& d, const ImageBuf& s) {
            return sure_in_working_space(d, s, denoiser, options, roi, nthreads,
                                         &s == &src ? &src : nullptr);
        });
}

ImageBuf sure(const ImageBuf& src, const Denoiser& denoiser, const SureOptions& options, ROI roi,
              int nthreads)
{
    ImageBuf dst;
    sure(dst, src, denoiser, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
