// Running stages by name (mcdn/chain.h).
#include "mcdn/chain.h"

#include <algorithm>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>

#include "chain/chain_steps.h"
#include "core/attributes.h"
#include "core/channels.h"
#include "core/frame_facts.h"
#include "core/op_prepare.h"
#include "core/progress.h"
#include "mcdn/color.h"
#include "mcdn/denoise.h"
#include "mcdn/settings.h"
#include "mcdn/stages.h"
#include "mcdn/sure.h"

namespace mcdn {

using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

namespace {

// The stages a chain may name (the Plan, denoise, only alone).
std::vector<std::string> chain_stages()
{
    return stage_names({ StageKind::Denoiser, StageKind::Estimator, StageKind::Mixer });
}

// One stage's settings out of the chain's "stage.key" settings, checked by the table's
// parser; the error names the setting as given.
bool checked_settings(Settings& settings, const StageInfo& stage, const ChainOptions& o,
                      std::string& error)
{
    settings = stage_settings(o.settings, stage.name);
    if (stage.check(settings, error))
        return true;
    error = stage.name + "." + error;  // "nfor.window=4 must be ..."
    return false;
}

// Every setting belongs to a stage and passes its checks, also for stages not in the chain:
// a misspelt key is an error, not silently the default.
bool check_settings(const ChainOptions& o, std::string& error)
{
    const std::vector<std::string> stages = chain_stages();
    for (const auto& [key, value] : o.settings) {
        std::string stage = key.substr(0, key.find('.'));
        // A plan's keys (denoise.extras) go to the stages it picks (run_stages).
        const StageInfo* plan = find_stage(stage);
        if (plan && plan->kind == StageKind::Plan
            && std::find(plan->keys.begin(), plan->keys.end(), key.substr(stage.size() + 1))
                   != plan->keys.end())
            continue;
        if (key.find('.') == std::string::npos
            || std::find(stages.begin(), stages.end(), stage) == stages.end()) {
            error = format("'{}': not a stage setting (stage.key, stages: {})", key,
                           Strutil::join(stages, ", "));
            return false;
        }
    }
    Settings settings;
    for (const std::string& name : stages)
        if (!checked_settings(settings, *find_stage(name), o, error))
            return false;
    return true;
}

// A stage of the chain made from its settings (check_settings has checked them).
bool make_stage(MadeStage& made, const std::string& name, const ChainOptions& o,
                StageContext context, std::string& error, int nthreads)
{
    const StageInfo& stage = *find_stage(name);
    Settings settings;
    context.aovs = o.aovs;
    context.progress = o.progress;
    context.nthreads = nthreads;
    return checked_settings(settings, stage, o, error)
           && stage.make(made, settings, context, error);
}

}  // namespace

bool parse_chain(std::vector<std::string>& stages, const std::string& text, std::string& error)
{
    stages = Strutil::splits(text, ",");
    bool seen_estimator = false;
    for (auto& s : stages) {
        const StageInfo* stage = find_stage(s);
        if (stage && stage->kind == StageKind::Plan) {
            if (stages.size() == 1) {
                s = stage->name;
                return true;  // the best chain the inputs allow (mcdn/denoise.h)
            }
            error = format("chain '{}': {} picks the whole chain itself; give it alone or "
                           "name the stages",
                           text, s);
            return false;
        }
        if (!stage) {
            error = format("unknown stage '{}' in chain '{}' (stages: {}, or {} alone)", s, text,
                           Strutil::join(chain_stages(), ", "),
                           Strutil::join(stage_names({ StageKind::Plan }), " or "));
            return false;
        }
        if (stage->kind == StageKind::Mixer && !seen_estimator) {
            error = format("chain '{}': {} needs {} before it", text, s,
                           Strutil::join(stage_names({ StageKind::Estimator }), " or "));
            return false;
        }
        seen_estimator |= stage->kind == StageKind::Estimator;
        s = stage->name;
    }
    if (stages.empty()) {
        error = "empty chain";
        return false;
    }
    return true;
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

// A stage that changes the features (the prefilter) makes the output keep the input's
// unless a stage of the chain asks for its own (features-out).
bool keeps_prefiltered_features(const ChainOptions& o)
{
    if (std::none_of(o.stages.begin(), o.stages.end(), [](const std::string& name) {
            const StageInfo* stage = find_stage(name);
            return stage && stage->changes_features;
        }))
        return true;
    for (const StageInfo& stage : stage_table()) {
        auto it = o.settings.find(stage.name + ".features-out");
        if (it != o.settings.end() && it->second != "0")
            return true;
    }
    return false;
}

// `own`: src itself, mutable (run_chain_on_own), or null.
bool run_stages(ImageBuf& dst, const ImageBuf& src, ImageBuf* own, const ChainOptions& o, ROI roi,
                int nthreads);
bool run_chain_impl(ImageBuf& dst, const ImageBuf& src, ImageBuf* own, const ChainOptions& o,
                    ROI roi, int nthreads);

// The chain in bands (chain_bands.cpp), its rows gathered into dst: the frame-sized result
// and one band are all that is allocated besides src.
bool run_chain_into(ImageBuf& dst, const ImageBuf& src, const ChainOptions& o, int nthreads)
{
    ImageBuf out;
    BandCounts counts;
    auto gather = [&](const ImageBuf& band, const ROI& own, std::string& error) {
        const ImageSpec& spec = band.spec();
        counts.add(spec);
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
    counts.set(out.specmod());
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

// A frame not in the working space (mcdn/color.h) goes there once for the whole chain, each
// stage would convert its input and result otherwise: our own input in place, else a copy;
// the result comes back. False when there is nothing to convert (dst untouched), else true
// with dst the result or its error.
bool run_in_working_space_once(ImageBuf& dst, const ImageBuf& src, ImageBuf* own,
                               const ChainOptions& o, ROI roi, int nthreads)
{
    std::string from, why, error;
    AovSet aovs;
    if (!input_colorspace(from, why, o.aovs, src.spec(), error)
        || !resolve_aovs(aovs, o.aovs, src.spec(), error)
        || !needs_working_conversion(src.spec(), from, aovs))
        return false;  // the stages say what is wrong
    ImageBuf copy;
    ImageBuf* converted = own;
    if (!own || own->spec().format != OIIO::TypeDesc::FLOAT || !own->localpixels()) {
        copy = copy_with_channels(src, {}, {}, nthreads);
        if (!copy.localpixels()) {
            dst.errorfmt("chain: out of memory for a float copy of the {}x{} frame of {} channels",
                         src.spec().width, src.spec().height, src.spec().nchannels);
            return true;
        }
        converted = &copy;
    }
    if (!into_working_space(*converted, aovs, from, error, nthreads)) {
        dst.errorfmt("chain: colorspace {}: {}", from, error);
        return true;
    }
    if (!run_chain_impl(dst, *converted, converted, o, roi, nthreads))
        return true;
    if (!resolve_aovs(aovs, o.aovs, dst.spec(), error)
        || !out_of_working_space(dst, aovs, from, error, nthreads))
        dst.errorfmt("chain: colorspace {}: {}", from, error);
    return true;
}

bool run_chain_impl(ImageBuf& dst, const ImageBuf& src, ImageBuf* own, const ChainOptions& o,
                    ROI roi, int nthreads)
{
    // A band of a larger frame (it carries the frame's facts) is never cut again.
    const bool whole_frame = (!roi.defined() || roi == src.roi()) && !is_frame_band(src.spec());
    if (o.band_pixels > 0 && whole_frame && int64_t(src.roi().npixels()) > o.band_pixels)
        return run_chain_into(dst, src, o, nthreads);
    if (run_in_working_space_once(dst, src, own, o, roi, nthreads))
        return !dst.has_error();
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
            const std::vector<std::string> output =
                Strutil::splits(src.spec().get_string_attribute(kOutputChannelsAttribute), "\n");
            if (!output.empty())
                features.erase(std::remove_if(features.begin(), features.end(),
                                              [&](const std::string& name) {
                                                  return std::find(output.begin(), output.end(),
                                                                   name)
                                                         == output.end();
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

bool run_stages(ImageBuf& dst, const ImageBuf& src, ImageBuf* own, const ChainOptions& given,
                ROI roi, int nthreads)
{
    ChainOptions o = given;
    std::vector<std::string> check;
    std::string error;
    if (!parse_chain(check, Strutil::join(o.stages, ","), error) || !check_settings(o, error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    if (o.stages.size() == 1 && find_stage(o.stages[0])->kind == StageKind::Plan) {
        // What mcdn::denoise runs, with this chain's bands.
        DenoisePlan plan;
        ChainOptions planned;
        if (!planned_chain(planned, src.spec(), o, error, &plan)) {
            dst.errorfmt("denoise: {}", error);
            return false;
        }
        if (!run_chain_impl(dst, src, own, planned, roi, nthreads))
            return false;
        dst.specmod().attribute("mcdn:denoise_plan", plan.describe());
        return true;
    }
    // The stages report one fraction of the whole chain (core/progress.h).
    o.progress = chain_progress(given.progress, o.stages);
    // The image the next stage reads: src itself until a stage has made another (an
    // ImageBuf copy would copy its pixels).
    ImageBuf made_image;
    const ImageBuf* current = &src;
    std::vector<std::pair<std::string, Denoiser>> pending;  // denoisers since the last sure/mix
    std::vector<StageReach> pending_reach;
    Denoiser estimated;  // the last Estimator's denoiser, a Mixer's (StageContext::denoiser)
    for (const std::string& name : o.stages) {
        const StageInfo& stage = *find_stage(name);
        MadeStage made;
        StageContext context;
        context.roi = roi;
        if (stage.kind == StageKind::Denoiser) {
            // Denoisers wait: a sure after them runs them itself (K + 1 times), else they
            // run at the end.
            if (!make_stage(made, name, o, context, error, nthreads)) {
                dst.errorfmt("{}", stage_error(name, error));
                return false;
            }
            pending_reach.push_back(made.reach);
            pending.emplace_back(name, std::move(made.run));
            continue;
        }
        ImageBuf next;
        // A mix runs in place on a result of the chain's own (not on src): a frame less.
        ImageBuf& out =
            stage.kind == StageKind::Mixer && current == &made_image ? made_image : next;
        // Probed in the chain's own input where it has one (a frame less).
        const bool probe_own = stage.kind == StageKind::Estimator && own && current == &src;
        if (stage.kind == StageKind::Estimator) {
            context.denoiser_radius = chain_radius(pending_reach);
            // A denoiser that writes only its colour and extras and reads no extra when
            // probed may run in the input itself (SureOptions::denoiser_in_place).
            context.denoiser_in_place =
                pending.size() == 1 && find_stage(pending[0].first)->probes_in_place;
            context.denoiser = compose_in_place(std::move(pending));
            estimated = context.denoiser;
            pending.clear();
            pending_reach.clear();
        } else if (stage.kind == StageKind::Mixer) {
            context.denoiser = estimated;
        }
        bool ok = make_stage(made, name, o, context, error, nthreads);
        if (!ok) {
            dst.errorfmt("{}", stage_error(name, error));
            return false;
        }
        ok = probe_own ? made.run_on_own(next, *own) : made.run(out, *current);
        // No later stage reads the chain's input (its features are kept apart): its pages
        // go back now (the mix's network is next). Assigned, not reset: sure may have made
        // it its result (moved from, it has no state to reset).
        if (ok && probe_own)
            *own = ImageBuf();
        if (!ok) {
            dst.errorfmt("{}", stage_error(name, out.geterror()));
            return false;
        }
        if (&out == &next)
            made_image = std::move(next);
        current = &made_image;
    }
    if (pending.empty()) {
        // Not `dst = cond ? src : std::move(made)`: that expression is a const prvalue,
        // so made would be copied, not moved.
        if (current == &src)
            dst.copy(src);
        else
            dst = std::move(made_image);
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
