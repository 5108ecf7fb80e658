// mcdn::denoise: the plan (mcdn/denoise.h says which chain and why), then run_chain.
#include "mcdn/denoise.h"

#include <OpenImageIO/strutil.h>

#include "chain/chain_steps.h"
#include "mcdn/chain.h"
#include "mcdn/cnn.h"
#include "mcdn/oidn.h"
#include "mcdn/stages.h"

namespace mcdn {

using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

std::string DenoisePlan::describe() const
{
    const auto choose_with = [&] {
        const auto it = settings.find("choose.with");
        return it == settings.end() ? std::string("nfor") : it->second;
    };
    std::vector<std::string> shown;
    for (const std::string& s : stages)
        shown.push_back(s == "mix"      ? "mix (net)"
                        : s == "choose" ? "choose (" + choose_with() + ")"
                                        : s);
    std::string line = Strutil::join(shown, " -> ") + ": " + why;
    if (!zero_filled.empty())
        line += "; no " + Strutil::join(zero_filled, ", ") + " (read as zero by the CNN)";
    return line;
}

bool plan_denoise(DenoisePlan& plan, const ImageSpec& merged, const AovSpec& spec,
                  std::string& error, const std::map<std::string, std::string>& settings)
{
    AovSet aovs;
    if (!resolve_aovs(aovs, spec, merged, error) || !aovs.require({ Role::Color }, merged, error))
        return false;
    plan = DenoisePlan();
    // OIDN's network where the user has its weights (mcdn/oidn.h), else our CNN.
    OidnOptions oidn;
    if (auto it = settings.find("oidn.weights"); it != settings.end())
        oidn.weights = it->second;
    const bool albedo = aovs.channels(Role::Albedo).size() == 3;
    const bool normal = aovs.channels(Role::Normal).size() == 3;
    std::string weights, unused;
    const bool has_oidn = oidn_weights(weights, oidn, albedo, normal, unused);
    const std::string denoiser = has_oidn ? "oidn" : "cnn";
    const bool halves = aovs.has(Role::ColorA) && aovs.has(Role::ColorB);
    plan.settings["mix.model"] = "net";
    if (aovs.has(Role::ColorVariance)) {
        plan.stages = { denoiser, "sure", "mix" };
        plan.why = format("the input has a colour variance ({})",
                          Strutil::join(aovs.names(Role::ColorVariance), ","));
        // A second denoiser weighed beside it per pixel by SURE (choose): NFOR beside the
        // CNN where the render has halves; our CNN beside OIDN where the render is clean
        // enough for SURE to tell the networks apart (kChooseNetworksMaxNoise). Not
        // cross-frame: the denoiser's input is then combined with its neighbours against
        // flicker, and choose's second denoiser would see this frame's alone.
        const auto frames = settings.find("denoise.frames");
        const bool cross_frame = frames != settings.end() && frames->second != "0";
        const auto choose = settings.find("denoise.choose");
        const bool off = choose != settings.end() && choose->second == "0";
        if (cross_frame) {
            plan.why += " (cross-frame: no second denoiser weighed beside it)";
        } else if (off) {
            plan.why += " (choose=0: no second denoiser weighed beside it)";
        } else if (has_oidn) {
            plan.stages.insert(plan.stages.begin() + 2, "choose");
            plan.settings["choose.with"] = "cnn";
            plan.why += " (our CNN beside OIDN, weighed per pixel by SURE where the render is "
                        "clean enough to tell them apart; choose=0: not)";
        } else if (halves) {
            plan.stages.insert(plan.stages.begin() + 2, "choose");
            plan.why +=
                " and half buffers (NFOR beside it, weighed per pixel by the halves' error estimate; "
                "choose=0: not)";
        }
    } else {
        plan.stages = { denoiser };
        plan.why = "no colour variance, which SURE and the mix need (render one, or give "
                   "-i:as=variance FILE, for the mixed chain)";
    }
    // denoise.extras: its denoisers' and choose's.
    if (auto it = settings.find("denoise.extras"); it != settings.end())
        for (const std::string& name : plan.stages)
            if (find_stage(name)->kind == StageKind::Denoiser || name == "choose")
                plan.settings[name + ".extras"] = it->second;
    if (has_oidn) {
        plan.why += "; OIDN's weights " + weights;
        if (!albedo || !normal)
            plan.why += albedo ? " (no normal)" : " (no albedo: the colour-only model)";
        return true;
    }
    // Which of our networks (mcdn/cnn.h): the colour + albedo + normal one on a frame with
    // neither the colour's variance nor the light split.
    const std::string cnn_weights = default_cnn_weights(&aovs);
    plan.why += "; our weights " + cnn_weights;
    if (Strutil::ends_with(cnn_weights, kColourAlbedoNormalWeights))
        plan.why += " (the model for colour, albedo and normal alone: a depth pass is not read)";
    for (Role r : { Role::Albedo, Role::Normal, Role::Depth })
        if (!aovs.has(r))
            plan.zero_filled.push_back(role_name(r));
    return true;
}

bool planned_chain(ChainOptions& planned, const ImageSpec& spec, const ChainOptions& o,
                   std::string& error, DenoisePlan* plan_out)
{
    planned = o;
    const StageInfo* stage = o.stages.size() == 1 ? find_stage(o.stages[0]) : nullptr;
    if (!stage || stage->kind != StageKind::Plan)
        return true;
    DenoisePlan plan;
    if (!plan_denoise(plan, spec, o.aovs, error, o.settings))
        return false;
    planned.stages = plan.stages;
    for (const auto& [key, value] : plan.settings)  // the caller's own settings win
        planned.settings.emplace(key, value);
    if (plan_out)
        *plan_out = std::move(plan);
    return true;
}

bool stage_can_run(const std::string& stage, const AovSet& aovs, std::string& how)
{
    const StageInfo* info = find_stage(stage);
    if (!info || !info->can_run) {
        how = "not a stage";
        return false;
    }
    if (!aovs.has(Role::Color)) {
        how = "no colour";
        return false;
    }
    return info->can_run(aovs, how);
}

bool denoise(ImageBuf& dst, const ImageBuf& src, const DenoiseOptions& options, ROI roi,
             int nthreads)
{
    // run_chain plans it (plan_denoise) and records the plan on dst.
    ChainOptions chain;
    chain.aovs = options.aovs;
    chain.stages = { "denoise" };
    chain.settings = options.settings;
    chain.progress = options.progress;
    return run_chain(dst, src, chain, roi, nthreads);
}

ImageBuf denoise(const ImageBuf& src, const DenoiseOptions& options, ROI roi, int nthreads)
{
    ImageBuf dst;
    denoise(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
