// Running stages by name (mcdn/chain.h).
#include "mcdn/chain.h"

#include <algorithm>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>

#include "chain/chain_steps.h"
#include "core/attributes.h"
#include "core/frame_facts.h"
#include "core/op_prepare.h"
#include "mcdn/cnn.h"
#include "mcdn/denoise.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/settings.h"
#include "mcdn/sure.h"
#include "sure/sure_steps.h"

namespace mcdn {

using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

namespace {

const std::vector<std::string> kStages = { "prefilter", "nfor", "cnn", "sure", "mix" };

// One stage's Options from the "stage.key" settings; the error names the setting as given.
template <class Options>
bool stage_options(Options& options, const ChainOptions& o, const std::string& stage,
                   std::string& error)
{
    options.aovs = o.aovs;
    options.progress = o.progress;
    if (apply_settings(options, stage_settings(o.settings, stage), error))
        return true;
    error = stage + "." + error;  // "nfor.window=4 must be ..."
    return false;
}

// Every setting belongs to a stage and passes its checks, also for stages not in the chain:
// a misspelt key is an error, not silently the default.
bool check_settings(const ChainOptions& o, std::string& error)
{
    for (const auto& [key, value] : o.settings) {
        std::string stage = key.substr(0, key.find('.'));
        if (key.find('.') == std::string::npos
            || std::find(kStages.begin(), kStages.end(), stage) == kStages.end()) {
            error = format("'{}': not a stage setting (stage.key, stages: {})", key,
                           Strutil::join(kStages, ", "));
            return false;
        }
    }
    PrefilterOptions p;
    NforOptions n;
    CnnOptions c;
    SureOptions s;
    MixOptions m;
    return stage_options(p, o, "prefilter", error) && stage_options(n, o, "nfor", error)
           && stage_options(c, o, "cnn", error) && stage_options(s, o, "sure", error)
           && stage_options(m, o, "mix", error);
}

// One denoiser of the chain, and how far it reaches (`reach`, for sure's bands).
std::pair<std::string, Denoiser> denoiser_stage(const std::string& name, const ChainOptions& o,
                                                int nthreads, StageReach& reach)
{
    std::string unused;  // check_settings has checked them
    reach = StageReach();
    if (name == "prefilter") {
        PrefilterOptions p;
        stage_options(p, o, name, unused);
        reach = stage_reach(p);
        return { name, [p, nthreads](ImageBuf& dst, const ImageBuf& src) {
                    return prefilter(dst, src, p, {}, nthreads);
                } };
    }
    if (name == "cnn") {
        CnnOptions c;
        stage_options(c, o, name, unused);
        reach = stage_reach(c);
        return { name, [c, nthreads](ImageBuf& dst, const ImageBuf& src) {
                    return cnn(dst, src, c, {}, nthreads);
                } };
    }
    NforOptions n;
    stage_options(n, o, name, unused);
    reach = stage_reach(n);
    return { name, [n, nthreads](ImageBuf& dst, const ImageBuf& src) {
                return nfor(dst, src, n, {}, nthreads);
            } };
}

}  // namespace

bool parse_chain(std::vector<std::string>& stages, const std::string& text, std::string& error)
{
    stages = Strutil::splits(text, ",");
    if (stages.size() == 1 && stages[0] == "denoise")
        return true;  // the best chain the inputs allow (mcdn/denoise.h)
    bool seen_sure = false;
    for (const auto& s : stages) {
        if (std::find(kStages.begin(), kStages.end(), s) == kStages.end()) {
            error = format(s == "denoise" ? "chain '{1}': denoise picks the whole chain itself; "
                                            "give it alone or name the stages"
                                          : "unknown stage '{0}' in chain '{1}' (stages: {2}, or "
                                            "denoise alone)",
                           s, text, Strutil::join(kStages, ", "));
            return false;
        }
        if (s == "mix" && !seen_sure) {
            error = format("chain '{}': mix needs sure before it", text);
            return false;
        }
        seen_sure |= s == "sure";
    }
    if (stages.empty()) {
        error = "empty chain";
        return false;
    }
    return true;
}

std::vector<std::string> feature_channel_names(const AovSet& aovs, const ImageSpec& spec)
{
    std::vector<std::string> names;
    for (Role base : { Role::Albedo, Role::Normal, Role::Depth, Role::Visibility })
        for (Face face : { Face::Mean, Face::Variance, Face::HalfA, Face::HalfB })
            for (int c : aovs.channels(face_of(base, face)))
                names.push_back(spec.channel_name(c));
    return names;
}

bool copy_channels_by_name(ImageBuf& dst, const ImageBuf& input,
                           const std::vector<std::string>& names, std::string& error)
{
    std::vector<float> plane;
    for (const std::string& name : names) {
        const int from = input.spec().channelindex(name), to = dst.spec().channelindex(name);
        if (from < 0 || to < 0) {
            error = format("channel '{}' is not in the {}", name, from < 0 ? "input" : "output");
            return false;
        }
        ROI r = input.roi();
        r.chbegin = from;
        r.chend = from + 1;
        ROI w = dst.roi();
        w.chbegin = to;
        w.chend = to + 1;
        plane.resize(r.npixels());
        if (r.npixels() != w.npixels() || !input.get_pixels(r, OIIO::TypeDesc::FLOAT, plane.data())
            || !dst.set_pixels(w, OIIO::TypeDesc::FLOAT, plane.data())) {
            error = format("could not copy channel '{}'", name);
            return false;
        }
    }
    return true;
}

namespace {

// A prefilter in the chain changes the features, which the output keeps only when asked.
bool keeps_prefiltered_features(const ChainOptions& o)
{
    if (std::find(o.stages.begin(), o.stages.end(), "prefilter") == o.stages.end())
        return true;
    for (const char* key : { "prefilter.features-out", "nfor.features-out" }) {
        auto it = o.settings.find(key);
        if (it != o.settings.end() && it->second != "0")
            return true;
    }
    return false;
}

// `own`: src itself, mutable (run_chain_on_own), or null.
bool run_stages(ImageBuf& dst, const ImageBuf& src, ImageBuf* own, const ChainOptions& o,
                ROI roi, int nthreads);
bool run_chain_impl(ImageBuf& dst, const ImageBuf& src, ImageBuf* own, const ChainOptions& o,
                    ROI roi, int nthreads);

// The chain in bands (chain_bands.cpp), its rows gathered into dst: the frame-sized result
// and one band are all that is allocated besides src.
bool run_chain_into(ImageBuf& dst, const ImageBuf& src, const ChainOptions& o, int nthreads)
{
    ImageBuf out;
    auto gather = [&](const ImageBuf& band, const ROI& own, std::string& error) {
        const ImageSpec& spec = band.spec();
        if (!out.initialized()) {
            ImageSpec frame = spec;
            frame.y = src.spec().y;
            frame.height = src.spec().height;
            if (!allocate_frame(out, frame, false)) {
                error = "chain: " + out.geterror();
                return false;
            }
        }
        if (spec.nchannels != out.nchannels() || spec.channelnames != out.spec().channelnames) {
            error = "chain: a band's result has other channels than the band above";
            return false;
        }
        ROI rows = own;
        rows.chbegin = 0;
        rows.chend = spec.nchannels;
        if (!band.get_pixels(rows, OIIO::TypeDesc::FLOAT, out.pixeladdr(rows.xbegin, rows.ybegin),
                             out.pixel_stride(), out.scanline_stride())) {
            error = "chain: " + band.geterror();
            return false;
        }
        return true;
    };
    std::string error;
    if (!run_chain(src, o, gather, error, nthreads)) {
        dst.errorfmt("{}", error);
        return false;
    }
    dst = std::move(out);
    return true;
}

}  // namespace

bool run_chain(ImageBuf& dst, const ImageBuf& src, const ChainOptions& o, ROI roi, int nthreads)
{
    return run_chain_impl(dst, src, nullptr, o, roi, nthreads);
}

bool run_chain_on_own(ImageBuf& dst, ImageBuf& src, const ChainOptions& o, int nthreads)
{
    return run_chain_impl(dst, src, &src, o, {}, nthreads);
}

namespace {

bool run_chain_impl(ImageBuf& dst, const ImageBuf& src, ImageBuf* own, const ChainOptions& o,
                    ROI roi, int nthreads)
{
    // A band of a larger frame (it carries the frame's facts) is never cut again.
    const bool whole_frame = (!roi.defined() || roi == src.roi())
                             && !is_frame_band(src.spec());
    if (o.band_pixels > 0 && whole_frame && int64_t(src.roi().npixels()) > o.band_pixels)
        return run_chain_into(dst, src, o, nthreads);
    const bool put_back = !keeps_prefiltered_features(o);
    AovSet aovs;
    std::string error;
    std::vector<std::string> features;
    if (put_back) {
        if (!resolve_aovs(aovs, o.aovs, src.spec(), error)) {
            dst.errorfmt("{}", error);
            return false;
        }
        features = feature_channel_names(aovs, src.spec());
        if (o.output_channels_only) {
            const std::vector<std::string> output = Strutil::splits(
                src.spec().get_string_attribute(kOutputChannelsAttribute), "\n");
            if (!output.empty())
                features.erase(std::remove_if(features.begin(), features.end(),
                                              [&](const std::string& name) {
                                                  return std::find(output.begin(), output.end(),
                                                                   name) == output.end();
                                              }),
                               features.end());
        }
    }
    // The chain's own input may be changed in place (run_stages): its features are kept
    // apart first, to be put back from there.
    ImageBuf kept;
    if (own && put_back && !features.empty()) {
        std::vector<int> channels;
        for (const std::string& name : features)
            channels.push_back(src.spec().channelindex(name));
        kept = OIIO::ImageBufAlgo::channels(src, int(channels.size()), channels, {}, features);
        if (kept.has_error()) {
            dst.errorfmt("keeping the input's features: {}", kept.geterror());
            return false;
        }
    }
    if (!run_stages(dst, src, own, o, roi, nthreads))
        return false;
    if (!put_back)
        return true;
    if (!copy_channels_by_name(dst, own ? kept : src, features, error)) {
        dst.errorfmt("putting back the input's features: {}", error);
        return false;
    }
    dst.specmod().erase_attribute("mcdn:prefiltered");
    return true;
}

bool run_stages(ImageBuf& dst, const ImageBuf& src, ImageBuf* own, const ChainOptions& o,
                ROI roi, int nthreads)
{
    std::vector<std::string> check;
    std::string error;
    if (!parse_chain(check, Strutil::join(o.stages, ","), error) || !check_settings(o, error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    if (o.stages.size() == 1 && o.stages[0] == "denoise") {
        // What mcdn::denoise runs, with this chain's bands.
        DenoisePlan plan;
        if (!plan_denoise(plan, src.spec(), o.aovs, error)) {
            dst.errorfmt("denoise: {}", error);
            return false;
        }
        ChainOptions planned = o;
        planned.stages = plan.stages;
        if (!planned.settings.count("mix.model"))
            planned.settings["mix.model"] = "net";
        if (!run_chain_impl(dst, src, own, planned, roi, nthreads))
            return false;
        dst.specmod().attribute("mcdn:denoise_plan", plan.describe());
        return true;
    }
    // The image the next stage reads: src itself until a stage has made another (an
    // ImageBuf copy would copy its pixels).
    ImageBuf made;
    const ImageBuf* current = &src;
    std::vector<std::pair<std::string, Denoiser>> pending;  // denoisers since the last sure/mix
    std::vector<StageReach> pending_reach;
    for (const std::string& name : o.stages) {
        if (name == "prefilter" || name == "nfor" || name == "cnn") {
            // Denoisers wait: a sure after them runs them itself (K + 1 times), else they
            // run at the end.
            pending_reach.emplace_back();
            pending.push_back(denoiser_stage(name, o, nthreads, pending_reach.back()));
            continue;
        }
        ImageBuf next;
        // mix runs in place on a result of the chain's own (not on src): a frame less.
        ImageBuf& out = name == "mix" && current == &made ? made : next;
        bool ok;
        if (name == "sure") {
            SureOptions s;
            stage_options(s, o, name, error);
            s.denoiser_radius = chain_radius(pending_reach);
            // The cnn alone writes only its colour and extras, and reads no extra when
            // probed: it may run in the input itself (SureOptions::denoiser_in_place).
            s.denoiser_in_place = pending.size() == 1 && pending[0].first == "cnn";
            // Probed in the chain's own input where it has one (a frame less).
            const bool probe_own = own && current == &src;
            ok = probe_own
                     ? sure_probing_src(next, *own, compose_in_place(std::move(pending)), s, roi,
                                        nthreads)
                     : sure(next, *current, compose_in_place(std::move(pending)), s, roi, nthreads);
            // No later stage reads the chain's input (its features are kept apart): its
            // pages go back now (the mix's network is next). Assigned, not reset: sure may
            // have made it its result (moved from, it has no state to reset).
            if (ok && probe_own)
                *own = ImageBuf();
            pending.clear();
            pending_reach.clear();
        } else {  // mix
            MixOptions m;
            stage_options(m, o, name, error);
            ok = mix(out, *current, m, roi, nthreads);
        }
        if (!ok) {
            dst.errorfmt("{}", stage_error(name, out.geterror()));
            return false;
        }
        if (&out == &next)
            made = std::move(next);
        current = &made;
    }
    if (pending.empty()) {
        // Not `dst = cond ? src : std::move(made)`: that expression is a const prvalue,
        // so made would be copied, not moved.
        if (current == &src)
            dst.copy(src);
        else
            dst = std::move(made);
        return true;
    }
    if (own && current == &src) {
        // The chain's own input is read by nothing after (its features are kept apart): the
        // denoisers run in place on it, no frame-sized copy each (prefilter and nfor read
        // their planes before they write, the cnn keeps the colour it reads apart).
        for (const auto& [name, stage] : pending)
            if (!stage(*own, *own)) {
                dst.errorfmt("{}", stage_error(name, own->geterror()));
                return false;
            }
        dst = std::move(*own);
        *own = ImageBuf();  // a moved-from ImageBuf has no state at all (not even empty)
        return true;
    }
    return compose_in_place(std::move(pending))(dst, *current);
}

}  // namespace

}  // namespace mcdn
