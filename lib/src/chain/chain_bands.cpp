// A chain in bands of rows (mcdn/chain.h): the whole frame's statistics first (a light pass:
// core/frame_facts.h), then every stage of the chain on one band at a time, its halo the
// chain's reach, each band's own rows handed on. Every stage computes on a band what it
// would on the whole frame: the frame's statistics travel on the band's spec, random probes
// are drawn by the pixel's index in the frame, and bands start on the converged-tile grid.
#include "mcdn/chain.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include <OpenImageIO/strutil.h>

#include "cnn/cnn_steps.h"
#include "core/bands.h"
#include "core/frame_facts.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "mcdn/cnn.h"
#include "mcdn/color.h"
#include "mcdn/denoise.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/settings.h"

namespace mcdn {

using OIIO::Strutil::fmt::format;

namespace {

// The stages the chain runs: "denoise" is planned here, once for the frame.
bool resolved_stages(std::vector<std::string>& stages, const ImageSpec& spec,
                     const ChainOptions& o, std::string& error)
{
    stages = o.stages;
    if (stages.size() == 1 && stages[0] == "denoise") {
        DenoisePlan plan;
        if (!plan_denoise(plan, spec, o.aovs, error))
            return false;
        stages = plan.stages;
    }
    return true;
}

// Channels holding one (sanitized) value over the frame, in one pass over its pixels.
std::map<std::string, float> constant_channels(const ImageBuf& src)
{
    const ImageSpec& spec = src.spec();
    const ROI whole = src.roi();
    const int nch = spec.nchannels;
    std::vector<float> first(nch), rows;
    std::vector<bool> constant(nch, true);
    const int rows_per_read = std::max(1, int((int64_t(1) << 20) / std::max<int64_t>(1, int64_t(whole.width()) * nch)));
    bool any = false;
    for (int y = whole.ybegin; y < whole.yend; y += rows_per_read) {
        ROI r = whole;
        r.ybegin = y;
        r.yend = std::min(y + rows_per_read, whole.yend);
        r.chbegin = 0;
        r.chend = nch;
        rows.resize(size_t(r.npixels()) * nch);
        src.get_pixels(r, OIIO::TypeDesc::FLOAT, rows.data());
        for (size_t p = 0; p < size_t(r.npixels()); ++p)
            for (int c = 0; c < nch; ++c) {
                const float v = sanitize(rows[p * nch + c]);
                if (!any)
                    first[c] = v;
                else if (!(v == first[c]))
                    constant[c] = false;
                if (c == nch - 1)
                    any = true;
            }
    }
    std::map<std::string, float> out;
    for (int c = 0; c < nch && any; ++c)
        if (constant[c])
            out[spec.channel_name(c)] = first[c];
    return out;
}

FrameFacts light_pass(const ImageBuf& src, const AovSet& aovs)
{
    FrameFacts facts;
    facts.ybegin = src.roi().ybegin;
    facts.yend = src.roi().yend;
    const std::vector<int>& colour = aovs.channels(Role::Color);
    const std::vector<int>& variance = aovs.channels(Role::ColorVariance);
    if (colour.size() == 3)
        facts.colour = colour_sums(src, colour.data(), variance.size() == 3 ? variance.data()
                                                                            : nullptr);
    const kpcn::DepthRange depth = kpcn::depth_range(src, aovs);
    facts.depth_lo = depth.lo;
    facts.depth_span = depth.span;
    facts.constant = constant_channels(src);
    return facts;
}

// Rows `cut` of src, every channel, as a float buffer of their own.
void copy_band(ImageBuf& band, const ImageBuf& src, const ROI& cut)
{
    ImageSpec spec = src.spec();
    spec.set_format(OIIO::TypeDesc::FLOAT);
    spec.channelformats.clear();
    spec.y = cut.ybegin;
    spec.height = cut.height();
    allocate_frame(band, spec, false);
    ROI all = cut;
    all.chbegin = 0;
    all.chend = spec.nchannels;
    src.get_pixels(all, OIIO::TypeDesc::FLOAT, band.localpixels());
}

}  // namespace

int chain_reach(const ImageSpec& spec, const ChainOptions& o)
{
    std::vector<std::string> stages;
    std::string error;
    if (!resolved_stages(stages, spec, o, error))
        return -1;
    int total = 0;
    bool prefiltered = false;
    std::string denoiser = "nfor";
    for (const std::string& name : stages) {
        const std::map<std::string, std::string> settings = stage_settings(o.settings, name);
        int r = 0;
        if (name == "prefilter") {
            PrefilterOptions p;
            r = apply_settings(p, settings, error) ? receptive_radius(p) : -1;
            prefiltered = true;
        } else if (name == "nfor") {
            NforOptions n;
            r = apply_settings(n, settings, error) ? receptive_radius(n, prefiltered) : -1;
            denoiser = "nfor";
        } else if (name == "cnn") {
            CnnOptions c;
            r = apply_settings(c, settings, error) ? receptive_radius(c) : -1;
            denoiser = "cnn";
        } else if (name == "mix") {
            MixOptions m;
            r = apply_settings(m, settings, error) ? receptive_radius(m, denoiser) : -1;
        }
        if (r < 0)
            return -1;
        total += r;
    }
    return total;
}

bool run_chain(const ImageBuf& input, const ChainOptions& o, const BandSink& sink,
               std::string& error, int nthreads)
{
    const ROI whole = input.roi();
    const int reach = chain_reach(input.spec(), o);
    // A band of a larger frame (it carries the frame's facts) is never cut again.
    const bool is_band = input.spec().find_attribute(kFrameFactsAttribute) != nullptr;
    const std::vector<Band> bands = reach >= 0 && !is_band
                                        ? plan_bands(whole, reach, o.band_pixels)
                                        : plan_bands(whole, 0, 0);
    if (bands.size() == 1) {
        ImageBuf result;
        ChainOptions whole_frame = o;
        whole_frame.band_pixels = 0;
        if (!run_chain(result, input, whole_frame, {}, nthreads)) {
            error = result.geterror();
            return false;
        }
        return sink(result, whole, error);
    }
    // The light pass and the bands in the working space (the stages then convert nothing);
    // each band's result back in the input's space before it is handed on.
    std::string from, why;
    if (!input_colorspace(from, why, o.aovs, input.spec(), error)) {
        error = "chain: " + error;
        return false;
    }
    const bool convert = from != working_colorspace();
    ImageBuf converted;
    AovSet aovs;
    if (!resolve_aovs(aovs, o.aovs, input.spec(), error))
        return false;
    if (convert) {
        converted = input.copy(OIIO::TypeDesc::FLOAT);
        if (!convert_color_channels(converted, aovs, from, working_colorspace(), error))
            return false;
        converted.specmod().attribute("mcdn:in_working_space", 1);
    }
    const ImageBuf& src = convert ? converted : input;
    const FrameFacts facts = light_pass(src, aovs);
    ChainOptions band_options = o;
    band_options.band_pixels = 0;
    for (size_t b = 0; b < bands.size(); ++b) {
        if (o.progress)
            band_options.progress = [&o, b, n = bands.size()](const std::string& stage,
                                                              float fraction) {
                o.progress(stage, (float(b) + fraction) / float(n));
            };
        ImageBuf band, result;
        copy_band(band, src, bands[b].cut);
        set_frame_facts(band.specmod(), facts);
        if (!run_chain(result, band, band_options, {}, nthreads)) {
            error = result.geterror();
            return false;
        }
        band.reset();
        result.specmod().erase_attribute(kFrameFactsAttribute);
        if (convert) {
            AovSet result_aovs;
            result.specmod().erase_attribute("mcdn:in_working_space");
            if (!resolve_aovs(result_aovs, o.aovs, result.spec(), error)
                || !convert_color_channels(result, result_aovs, working_colorspace(), from,
                                           error))
                return false;
        }
        ROI own = whole;
        own.ybegin = bands[b].own_begin;
        own.yend = bands[b].own_end;
        if (!sink(result, own, error))
            return false;
    }
    return true;
}

}  // namespace mcdn
