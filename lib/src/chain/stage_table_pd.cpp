// The stage table's entries for Progressive Denoising's stages (mcdn/stages.h): sure (§2.3,
// §3.2), choose (§3.2's decision by SURE, with NFOR beside the denoiser) and mix (§4).
#include "chain/settings_reader.h"
#include "chain/stage_entries.h"

#include "mcdn/choose.h"
#include "mcdn/mix.h"
#include "mcdn/sure.h"
#include "sure/sure_steps.h"

namespace mcdn {
namespace stage_entries {

// ---- sure (PD §2.3, §3.2) -------------------------------------------------------------

bool make_sure(MadeStage& made, const Settings& settings, const StageContext& context,
               std::string& error)
{
    SureOptions o;
    if (!options_of(o, settings, context, error))
        return false;
    o.denoiser_radius = context.denoiser_radius;
    o.denoiser_in_place = context.denoiser_in_place;
    const Denoiser denoiser = context.denoiser;
    const int n = context.nthreads;
    const ROI roi = context.roi;
    made.reach = { 0, 0, false };  // no further than its denoisers
    made.run = [o, denoiser, roi, n](ImageBuf& dst, const ImageBuf& src) {
        return sure(dst, src, denoiser, o, roi, n);
    };
    made.run_on_own = [o, denoiser, roi, n](ImageBuf& dst, ImageBuf& own) {
        return sure_probing_src(dst, own, denoiser, o, roi, n);
    };
    return true;
}

bool sure_can_run(const AovSet& aovs, std::string& how)
{
    const bool variance = aovs.has(Role::ColorVariance);
    how = variance ? "after a denoiser" : "needs the colour's variance";
    return variance;
}

StageInfo sure_stage()
{
    StageInfo s;
    s.name = "sure";
    s.kind = StageKind::Estimator;
    s.keys = { "probes", "eps", "seed", "fallback", "fallback-aov", "skip", "converged" };
    s.facts.color_sums = true;
    s.frame_buffers = 1.5;  // the noisy copy and the denoiser's responses
    s.help =
        "Monte-Carlo SURE of the denoisers before it (PD §3.2): adds sure.*, "
        "sure.divergence.*, sure.residual.* and noisy.* channels. probes=1 (K; costs K+1 "
        "denoiser runs), eps=1e-3 (relative probe step). -v says in how many 32x32 tiles SURE "
        "finds the denoiser worse than the render, and those tiles are the render (safety net, "
        "for any denoiser; fallback=0: the denoiser's are kept); fallback-aov=1 adds channel "
        "sure.fallback, 1 on those tiles.";
    s.needs = "the colour and the variance of its mean, and a denoiser before it (--cnn, --nfor, "
              "--prefilter --nfor), which it runs probes+1 times.";
    s.check = check_settings<SureOptions>;
    s.make = make_sure;
    s.can_run = sure_can_run;
    return s;
}

// ---- mix (PD §4) ----------------------------------------------------------------------

bool make_mix(MadeStage& made, const Settings& settings, const StageContext& context,
              std::string& error)
{
    MixOptions o;
    if (!options_of(o, settings, context, error))
        return false;
    made.run = [o, roi = context.roi, n = context.nthreads](ImageBuf& dst, const ImageBuf& src) {
        return mix(dst, src, o, roi, n);
    };
    return true;
}

StageReach mix_reach(const Settings& settings, const std::string& denoiser)
{
    MixOptions o;
    std::string error;
    const int r = apply_settings(o, settings, error) ? receptive_radius(o, denoiser) : -1;
    return { r, r, false };
}

bool mix_can_run(const AovSet& aovs, std::string& how)
{
    const bool variance = aovs.has(Role::ColorVariance);
    how = variance ? "after --sure" : "needs the colour's variance";
    return variance;
}

StageInfo mix_stage()
{
    StageInfo s;
    s.name = "mix";
    s.kind = StageKind::Mixer;
    s.keys = { "model",   "weights", "ttest", "alpha",    "afloor",
               "outlier", "drop",    "skip",  "converged" };
    s.facts.color_sums = true;
    s.frame_buffers = 0.8;  // the result
    s.help = "Progressive mix of the render and the denoised image (PD §4), after --sure: "
             "model=net|analytic (default net), ttest=1 bounds alpha by the t-test (eq. 18), "
             "alpha=1 adds "
             "mix.alpha.* channels; with model=net: the network trained for the denoiser before "
             "--sure (models/mix_cnn.mcdnw after --cnn, mix_oidn.mcdnw after --oidn, else "
             "models/mix.mcdnw; weights=FILE), "
             "afloor=1, alpha is at least the analytic model's; with either model: "
             "outlier=0.3, alpha is at least eq. 9 where the "
             "render's variance exceeds 0.3 (y^2 + 0.01), drop=1.5: alpha = 1 where it exceeds "
             "1.5 (y^2 + 0.01) (0: off).";
    s.needs = "what --sure adds (sure.*, noisy.*): give --sure first; the colour's variance.";
    s.check = check_settings<MixOptions>;
    s.make = make_mix;
    s.reach = mix_reach;
    s.can_run = mix_can_run;
    return s;
}

// ---- choose (PD §3.2, NFOR §5.3's selection) -------------------------------------------

// NFOR as choose runs it (prefilter, nfor at their defaults) and how far it reaches.
bool make_nfor_chain(Denoiser& denoiser, int& radius, const ChooseOptions& o,
                     const StageContext& context, std::string& error)
{
    StageContext quiet = context;
    quiet.progress = {};  // choose reports for it
    quiet.previous_frames.clear();
    quiet.next_frames.clear();
    MadeStage prefilter, nfor;
    if (!make_prefilter(prefilter, {}, quiet, error)
        || !make_nfor(nfor, { { "extras", o.denoise_extras ? "1" : "0" } }, quiet, error))
        return false;
    radius = chain_radius({ prefilter.reach, nfor.reach });
    denoiser = compose_in_place(
        { { "prefilter", std::move(prefilter.run) }, { "nfor", std::move(nfor.run) } });
    return true;
}

bool choose_settings(ChooseOptions& o, const Settings& s, std::string& error)
{
    return SettingsReader(s, "choose", error)
        .width("window", o.window_radius)
        .width("blend", o.blend_radius)
        .positive_int("probes", o.sure.probes)
        .flag("extras", o.denoise_extras)
        .flag("weight-aov", o.output_weight)
        .ok();
}

// Its NFOR's reach (prefilter, nfor at their defaults, as choose runs them), then its windows'.
StageReach choose_reach(const ChooseOptions& o)
{
    const int r = chain_radius({ stage_reach(PrefilterOptions()), stage_reach(NforOptions()) })
                  + receptive_radius(o);
    return { r, r, false };
}

bool make_choose(MadeStage& made, const Settings& settings, const StageContext& context,
                 std::string& error)
{
    ChooseOptions o;
    Denoiser other;
    if (!choose_settings(o, settings, error))
        return false;
    o.aovs = context.aovs;
    o.progress = context.progress;
    if (!make_nfor_chain(other, o.other_radius, o, context, error))
        return false;
    made.reach = choose_reach(o);
    made.run = [o, other, roi = context.roi, n = context.nthreads](ImageBuf& dst,
                                                                   const ImageBuf& src) {
        return choose(dst, src, other, o, roi, n);
    };
    return true;
}

StageInfo choose_stage()
{
    StageInfo s;
    s.name = "choose";
    s.kind = StageKind::Mixer;
    s.keys = { "window", "blend", "probes", "extras", "weight-aov" };
    s.reads_halves = true;
    s.facts.color_sums = true;
    s.facts.constant_features = true;
    s.frame_buffers = 4.0;  // the render rebuilt, NFOR's result with its SURE, NFOR's own
    s.help = "After --cnn (or --oidn) --sure: runs NFOR (--prefilter --nfor) and its SURE on "
             "the render, and weighs the two per pixel by their SURE summed over the window "
             "around it, relative to the value and the render's variance (each its share of "
             "the inverse errors: PD §3.2, NFOR §5.3), the weight smoothed; light AOVs take the "
             "same weights, so they still add up. --mix after it mixes the result with the "
             "render. window=17 (the sums' width), blend=9 (the weight's smoothing), probes=1 "
             "(NFOR's SURE costs probes+1 NFOR runs), weight-aov=1 adds channel choose.weight "
             "(1: NFOR's). --denoise runs it where the render has half buffers.";
    s.needs = "what --sure adds after a denoiser; the colour's half buffers and variance (NFOR "
              "§5's input).";
    s.check = [](const Settings& settings, std::string& error) {
        ChooseOptions o;
        return choose_settings(o, settings, error);
    };
    s.make = make_choose;
    s.reach = [](const Settings& settings, const std::string&) {
        ChooseOptions o;
        std::string error;
        return choose_settings(o, settings, error) ? choose_reach(o) : StageReach();
    };
    s.can_run = [](const AovSet& aovs, std::string& how) {
        const bool ok = has_halves(aovs) && aovs.has(Role::ColorVariance);
        how = ok ? "after --sure: NFOR on the halves, weighed per pixel by SURE"
                 : "needs the colour's half buffers and variance";
        return ok;
    };
    return s;
}

}  // namespace stage_entries
}  // namespace mcdn
