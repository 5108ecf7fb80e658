// A chain in bands of rows (mcdn/chain.h): the whole frame's statistics first (a light pass:
// core/frame_facts.h), then every stage of the chain on one band at a time, its halo the
// chain's reach, each band's own rows handed on. Every stage computes on a band what it
// would on the whole frame: the frame's statistics travel on the band's spec, random probes
// are drawn by the pixel's index in the frame, and bands start on the converged-tile grid.
#include "mcdn/chain.h"

#include <algorithm>

#include <OpenImageIO/strutil.h>

#include "cnn/cnn_steps.h"
#include "core/bands.h"
#include "core/channels.h"
#include "core/frame_facts.h"
#include "core/planar.h"
#include "core/trace.h"
#include "mcdn/cnn.h"
#include "mcdn/color.h"
#include "mcdn/denoise.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/settings.h"

namespace mcdn {

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

// Which feature channels (every face of albedo, normal, depth, visibility, and any channel a
// stage's features= names) and extra AOV channels hold one sanitized value over the frame:
// one pass over the frame's rows, every channel at once (a channel at a time would stride
// through all of them once per channel).
std::map<std::string, float> constant_features(const ImageBuf& src, const AovSet& aovs,
                                               const ChainOptions& o)
{
    const ImageSpec& spec = src.spec();
    std::vector<std::string> names = feature_channel_names(aovs, spec);
    // The extras' means and halves too: an empty one is left out (core/extra_aovs.h).
    for (const AovSet::Extra& extra : aovs.extras())
        for (const std::vector<int>* channels : { &extra.channels, &extra.half_a, &extra.half_b })
            for (int ch : *channels)
                names.push_back(spec.channel_name(ch));
    for (const char* key : { "prefilter.features", "nfor.features" })
        if (auto it = o.settings.find(key); it != o.settings.end())
            for (const std::string& name : OIIO::Strutil::splits(it->second, ","))
                for (const std::string& face : { name, "variance." + name, "A." + name, "B." + name })
                    if (spec.channelindex(face) >= 0)
                        names.push_back(face);
    std::vector<int> channels;
    for (const std::string& name : names)
        channels.push_back(spec.channelindex(name));
    const ROI whole = src.roi();
    const int nch = spec.nchannels, nf = int(channels.size());
    std::vector<float> first(nf);
    std::vector<char> constant(nf, 1);
    std::vector<float> rows;
    const int rows_per_read
        = std::max(1, int((int64_t(1) << 22) / std::max<int64_t>(1, int64_t(whole.width()) * nch)));
    for (int y = whole.ybegin; y < whole.yend && nf > 0; y += rows_per_read) {
        ROI r = whole;
        r.ybegin = y;
        r.yend = std::min(y + rows_per_read, whole.yend);
        r.chbegin = 0;
        r.chend = nch;
        rows.resize(size_t(r.npixels()) * nch);
        src.get_pixels(r, OIIO::TypeDesc::FLOAT, rows.data());
        if (y == whole.ybegin)
            for (int f = 0; f < nf; ++f)
                first[f] = sanitize(rows[size_t(channels[f])]);
        for (int f = 0; f < nf; ++f) {
            if (!constant[f])
                continue;
            const float* v = rows.data() + channels[f];
            const float value = first[f];
            bool same = true;
            for (size_t p = 0; p < size_t(r.npixels()) && same; ++p)
                same = sanitize(v[p * nch]) == value;
            constant[f] = same;
        }
    }
    std::map<std::string, float> out;
    for (int f = 0; f < nf; ++f)
        if (constant[f])
            out[names[f]] = first[f];
    return out;
}

FrameFacts light_pass(const ImageBuf& src, const AovSet& aovs, const ChainOptions& o)
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
    facts.has_depth = true;
    facts.depth_lo = depth.lo;
    facts.depth_span = depth.span;
    facts.has_constant = true;
    facts.constant = constant_features(src, aovs, o);
    return facts;
}

}  // namespace

int chain_reach(const ImageSpec& spec, const ChainOptions& o)
{
    std::vector<std::string> stages;
    std::string error;
    if (!resolved_stages(stages, spec, o, error))
        return -1;
    // Each stage's reach; chain_radius knows that nfor reaches less after a prefilter.
    std::vector<StageReach> reaches;
    std::string denoiser = "nfor";
    for (const std::string& name : stages) {
        const std::map<std::string, std::string> settings = stage_settings(o.settings, name);
        StageReach reach { 0, 0, false };  // sure reaches no further than its denoiser
        if (name == "prefilter") {
            PrefilterOptions p;
            reach = apply_settings(p, settings, error) ? stage_reach(p) : StageReach();
        } else if (name == "nfor") {
            NforOptions n;
            reach = apply_settings(n, settings, error) ? stage_reach(n) : StageReach();
            denoiser = "nfor";
        } else if (name == "cnn") {
            CnnOptions c;
            reach = apply_settings(c, settings, error) ? stage_reach(c) : StageReach();
            denoiser = "cnn";
        } else if (name == "mix") {
            MixOptions m;
            const int r = apply_settings(m, settings, error) ? receptive_radius(m, denoiser) : -1;
            reach = { r, r, false };
        }
        reaches.push_back(reach);
    }
    return chain_radius(reaches);
}

bool run_chain(const ImageBuf& input, const ChainOptions& o, const BandSink& sink,
               std::string& error, int nthreads)
{
    const ROI whole = input.roi();
    const int reach = chain_reach(input.spec(), o);
    // A band of a larger frame (it carries the frame's facts) is never cut again.
    const bool is_band = is_frame_band(input.spec());
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
    StageTrace trace("chain");
    trace.mark("(before the chain)");
    const FrameFacts facts = light_pass(src, aovs, o);
    trace.mark("light pass (frame facts)");
    ChainOptions band_options = o;
    band_options.band_pixels = 0;
    for (size_t b = 0; b < bands.size(); ++b) {
        if (o.progress)
            band_options.progress = [&o, b, n = bands.size()](const std::string& stage,
                                                              float fraction) {
                o.progress(stage, (float(b) + fraction) / float(n));
            };
        // Rows of src, every channel, as a float buffer of their own.
        ImageBuf band = copy_with_channels(src, {}, bands[b].cut, nthreads), result;
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
        trace.mark("band: stages and its rows out");
    }
    return true;
}

}  // namespace mcdn
