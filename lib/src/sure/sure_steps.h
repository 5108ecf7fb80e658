// The steps of Monte-Carlo SURE (sure.cpp runs them): what is fixed on the whole frame first
// (the probe step, the output's channels), then each band's denoiser runs and probes.
// A small frame is one band; a large one runs in bands of SureOptions::band_pixels with the
// denoiser's radius as halo, and gets the same result because nothing a band computes
// depends on where the band starts: eps is the frame's, and probe b is drawn by the pixel's
// index in the frame (core/random.h), so a pixel sees the same probe in every band.
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "ops/bands.h"
#include "mcdn/aov.h"
#include "mcdn/sure.h"

namespace mcdn {

/// What every band of one frame shares.
struct SureFrame {
    ROI whole;             // the frame's data window
    int index_origin = 0;  // the first row of the probes' index space (a band's frame)
    ROI where;             // where the SURE channels are written (zero outside)
    std::vector<int> color, variance;
    std::vector<int> moved;   // colour and half buffers: what a probe moves
    std::vector<int> extras;  // x of the RGB extra AOVs, recorded as noisy.<name>
    std::vector<std::string> extra_names;
    double eps = 0;                 // the probe step (core/frame_facts.h relative_probe_step)
    bool fallback_channel = false;  // sure.fallback (SureOptions::output_fallback)
    // The denoiser runs on noisy itself (SureOptions::denoiser_in_place) and noisy, which
    // already has sure's channels, becomes dst: the band is the whole frame.
    bool denoise_in_place = false;
    int nthreads = 0;  // for SURE's own per-pixel work (the op's nthreads)
};

/// The channels sure adds, in the order it writes them: noisy.*, sure.*, sure.divergence.*,
/// sure.residual.*, then noisy.<extra>, then sure.fallback when asked for.
std::vector<std::string> sure_channel_names(const SureFrame& frame);
/// The same for a frame whose AOVs are `aovs`, with `options`.
std::vector<std::string> sure_channel_names(const AovSet& aovs, const SureOptions& options);
/// The RGB extra AOVs of `aovs` into frame.extras and frame.extra_names (so that mix can
/// mix them too).
void add_extras(SureFrame& frame, const AovSet& aovs);

/// mcdn::sure on a src that is the caller's own: when the frame is one band, its probes are
/// made in src itself, not in a copy (a frame-sized copy less), and src's pixels and spec
/// are as they were when it returns (also on failure). Meanwhile nothing else may read src.
/// When src has sure's channels already and options.denoiser_in_place, the denoiser runs
/// in src too and src becomes dst (moved: src is left without state).
bool sure_probing_src(ImageBuf& dst, ImageBuf& src, const Denoiser& denoiser,
                      const SureOptions& options, ROI roi = {}, int nthreads = 0);

/// Runs the denoiser on `noisy` (one band of the frame, its own float copy: probed in place)
/// K + 1 times and writes the band's own rows of dst: the denoised channels, noisy.*, sure.*,
/// sure.divergence.*, sure.residual.*, noisy.<extra>. The first band allocates dst (the
/// frame's window, the denoiser's channels plus those). `noisy` comes with those channels
/// (zero), or asks for them (kOutputRoomAttribute, dropped after the unprobed run): a
/// denoiser that keeps every channel then returns them, and when the band is the whole
/// frame its result becomes dst itself, without a frame-sized copy. False with
/// `error` on failure.
bool sure_band(ImageBuf& dst, ImageBuf& noisy, const Band& band, const Denoiser& denoiser,
               const SureOptions& options, const SureFrame& frame, std::string& error);

}  // namespace mcdn
