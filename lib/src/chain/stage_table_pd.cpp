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
    s.reads_all_variances = with_no_settings;  // the colour's
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
    s.reads_all_variances = with_no_settings;  // the colour's
    s.reach = mix_reach;
    s.can_run = mix_can_run;
    return s;
}

// ---- choose (PD §3.2, NFOR §5.3's selection) -------------------------------------------

// The stage's settings: ChooseOptions', and `with`, the denoiser choose runs beside the one
// before it: nfor (prefilter, nfor at their defaults), or a Denoiser of the table (cnn, oidn)
// at its defaults.
struct ChooseSettings {
    ChooseOptions o;
    std::string with = "nfor";
};

// estimate=halves|sure; default halves beside NFOR (measured there: mcdn/choose.h), SURE
// beside a network (kChooseNetworksMaxNoise was measured with it).
ChooseEstimate default_estimate(const std::string& with)
{
    return with == "nfor" ? ChooseEstimate::Halves : ChooseEstimate::Sure;
}

bool choose_settings(ChooseSettings& c, const Settings& s, std::string& error)
{
    SettingsReader reader(s, "choose", error);
    reader.width("window", c.o.window_radius)
        .width("blend", c.o.blend_radius)
        .positive_int("probes", c.o.sure.probes)
        .flag("extras", c.o.denoise_extras)
        .flag("weight-aov", c.o.output_weight)
        .custom("with", "must be nfor, cnn or oidn", [&](const std::string& v) {
            c.with = v;
            return v == "nfor" || v == "cnn" || v == "oidn";
        });
    // NFOR beside the CNN everywhere; a network beside OIDN where SURE can tell them apart.
    c.o.max_noise = c.with == "nfor" ? 0.0f : kChooseNetworksMaxNoise;
    c.o.estimate = default_estimate(c.with);
    return reader.number("noise", c.o.max_noise)
        .custom("estimate", "must be halves or sure",
                [&](const std::string& v) {
                    c.o.estimate = v == "halves" ? ChooseEstimate::Halves : ChooseEstimate::Sure;
                    return v == "halves" || v == "sure";
                })
        .custom("noise", "must be at least 0",
                [&](const std::string&) { return c.o.max_noise >= 0; })
        .ok();
}

// The settings choose hands the denoiser it runs: its extras as choose's (on the halves
// none: only their colour is read).
Settings with_settings(const ChooseSettings& c, bool on_halves = false)
{
    return { { "extras", c.o.denoise_extras && !on_halves ? "1" : "0" } };
}

// The denoiser choose runs as it runs it; how far it reaches and what it reads into c.o.
bool make_other(Denoiser& denoiser, ChooseSettings& c, const StageContext& context,
                std::string& error)
{
    StageContext quiet = context;
    quiet.progress = {};  // choose reports for it
    quiet.previous_frames.clear();
    quiet.next_frames.clear();
    if (c.with != "nfor") {
        MadeStage made, on_halves;
        if (!find_stage(c.with)->make(made, with_settings(c), quiet, error)
            || !find_stage(c.with)->make(on_halves, with_settings(c, true), quiet, error))
            return false;
        c.o.other_radius = chain_radius({ made.reach });
        // SURE's only denoiser on choose's own copy of the render: it may run in that copy.
        c.o.sure.denoiser_in_place = find_stage(c.with)->probes_in_place;
        denoiser = std::move(made.run);
        c.o.other_on_halves = std::move(on_halves.run);
        return true;
    }
    c.o.other_needs_halves = true;
    MadeStage prefilter, nfor, nfor_halves;
    if (!make_prefilter(prefilter, {}, quiet, error)
        || !make_nfor(nfor, with_settings(c), quiet, error)
        || !make_nfor(nfor_halves, with_settings(c, true), quiet, error))
        return false;
    c.o.other_radius = chain_radius({ prefilter.reach, nfor.reach });
    c.o.other_on_halves = compose_in_place(
        { { "prefilter", prefilter.run }, { "nfor", std::move(nfor_halves.run) } });
    denoiser = compose_in_place(
        { { "prefilter", std::move(prefilter.run) }, { "nfor", std::move(nfor.run) } });
    return true;
}

// Its denoiser's reach (as choose runs it; with the halves, the farther of it and the one
// before, `before`, at its defaults), then its windows'.
StageReach choose_reach(const ChooseSettings& c, const std::string& before)
{
    int other = c.with == "nfor"
                    ? chain_radius({ stage_reach(PrefilterOptions()), stage_reach(NforOptions()) })
                    : chain_radius({ find_stage(c.with)->reach(with_settings(c), "") });
    const StageInfo* stage = find_stage(before);
    if (c.o.estimate == ChooseEstimate::Halves && stage && stage->reach) {
        const int r = chain_radius({ stage->reach({}, "") });
        other = r < 0 ? -1 : std::max(other, r);
    }
    if (other < 0)
        return {};
    const int r = other + receptive_radius(c.o);
    return { r, r, false };
}

bool make_choose(MadeStage& made, const Settings& settings, const StageContext& context,
                 std::string& error)
{
    ChooseSettings c;
    Denoiser other;
    if (!choose_settings(c, settings, error))
        return false;
    c.o.aovs = context.aovs;
    c.o.progress = context.progress;
    c.o.before = context.denoiser;
    if (!make_other(other, c, context, error))
        return false;
    made.reach = choose_reach(c, "");  // read for Denoisers only; bands read StageInfo::reach
    made.run = [o = c.o, other, roi = context.roi, n = context.nthreads](ImageBuf& dst,
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
    s.keys = { "window", "blend", "probes", "extras", "weight-aov", "with", "noise", "estimate" };
    // What any of its denoisers reads (the table's flags are not per setting, but for the
    // halves): NFOR the halves and constant features, the CNN the light split and depth
    // range, OIDN the exposure.
    s.reads_halves = [](const Settings& settings) {  // NFOR's
        ChooseSettings c;
        std::string error;
        return !choose_settings(c, settings, error) || c.with == "nfor";
    };
    s.reads_light_split = true;
    s.facts.color_sums = true;
    s.facts.constant_features = true;
    s.facts.depth_range = true;
    s.facts.exposure = true;
    s.frame_buffers = 4.0;  // the render rebuilt, the other's result with its SURE, its own
    s.held_bytes = [](const Settings& settings, int threads) {
        ChooseSettings c;
        std::string error;
        const StageInfo* with =
            choose_settings(c, settings, error) && c.with != "nfor" ? find_stage(c.with) : nullptr;
        return with && with->held_bytes ? with->held_bytes(with_settings(c), threads) : 0.0;
    };
    s.help = "After a denoiser and --sure (--cnn --sure, --oidn --sure): runs a second "
             "denoiser and its SURE on the render, and weighs the two per pixel by their "
             "errors over the window around it, relative to the value and the render's "
             "variance. estimate=halves (with=nfor's default): both denoisers run on each half "
             "buffer, the other half the target (NFOR §5.3's estimate), the least-squares "
             "blend of the two where it lowers the error by more than 2 standard errors; "
             "estimate=sure (with=cnn or oidn): each its share of the inverse SUREs (PD §3.2). "
             "The weight is smoothed; light AOVs take the same weights, so they still add up. "
             "--mix after it "
             "mixes the result with the render. with=nfor (--prefilter --nfor: the halves), "
             "cnn or oidn (at their defaults), the second denoiser; noise=0.003 (with=cnn or "
             "oidn; with=nfor: 0, everywhere): the second weighs only where the render's "
             "relative variance Var/(y^2+0.01), averaged over the window, is below it (where two "
             "networks' SUREs cannot tell them apart) and is not run where it weighs nowhere; "
             "window=17 (the sums' width), blend=9 (the weight's smoothing), probes=1 (its "
             "SURE costs probes+1 runs of it), weight-aov=1 adds channel choose.weight (1: the "
             "second's). --denoise runs it: NFOR beside the CNN where the render has half "
             "buffers, the CNN beside OIDN.";
    s.needs = "what --sure adds after a denoiser; the colour's variance; with=nfor its half "
              "buffers too (NFOR §5's input).";
    s.check = [](const Settings& settings, std::string& error) {
        ChooseSettings c;
        return choose_settings(c, settings, error);
    };
    s.make = make_choose;
    s.reach = [](const Settings& settings, const std::string& before) {
        ChooseSettings c;
        std::string error;
        return choose_settings(c, settings, error) ? choose_reach(c, before) : StageReach();
    };
    // As with=nfor, its default, runs.
    s.can_run = [](const AovSet& aovs, std::string& how) {
        const bool ok = has_halves(aovs) && aovs.has(Role::ColorVariance);
        how = ok ? "after --sure: NFOR on the halves, weighed per pixel by the halves' estimate"
                 : "needs the colour's half buffers and variance";
        return ok;
    };
    return s;
}

}  // namespace stage_entries
}  // namespace mcdn
