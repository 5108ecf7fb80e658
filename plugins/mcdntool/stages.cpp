// The denoising stages as mcdntool commands: each maps its modifiers onto the stage's
// Options. Denoisers (--prefilter, --nfor) queue up; the next command that needs pixels runs
// them, and --sure takes the queued chain as the denoiser whose error it estimates.
#include <algorithm>
#include <iostream>

#include <OpenImageIO/strutil.h>

#include "mcdn/cnn.h"
#include "mcdn/denoise.h"
#include "mcdn/frames.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/settings.h"
#include "mcdn/sure.h"

#include "session.h"

namespace mcdntool {

using OIIO::ImageBuf;
using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

namespace {

// The stages' Options from their modifiers, parsed by the library's settings parser (the
// recipe and Python take the same keys); the AOV spec is the session's. No side effects, so
// the same functions check the command line before anything runs.
template <class Options>
bool stage_options(const Command& c, Options& o, std::string& error)
{
    if (mcdn::apply_settings(o, c.modifiers, error))
        return true;
    error = c.name + ":" + error;  // "--nfor:window=4 must be ..."
    return false;
}

template <class Options>
bool check(const Command& c, std::string& error)
{
    Options o;
    return stage_options(c, o, error);
}

bool queue_prefilter(Session& s, const Command& c, std::string& error)
{
    mcdn::PrefilterOptions o;
    if (!stage_options(c, o, error))
        return false;
    o.aovs = s.aov_spec;
    o.progress = s.progress();
    s.prefilters = true;
    s.features_out |= o.features_out;
    s.queue("prefilter", [o](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::prefilter(dst, src, o, {}, nthreads);
    }, mcdn::stage_reach(o));
    return true;
}

// `frames=N` of a cross-frame stage (--nfor: NFOR §8; --cnn, --denoise: the frames
// combined first, mcdn/frames.h): the front end's modifier, as mcdntool reads the frames; the
// rest are the stage's settings.
bool frames_of(const Command& c, int& frames, Command& settings, std::string& error)
{
    settings = c;
    frames = 0;
    if (!c.has("frames"))
        return true;
    const std::string text = c.modifier("frames");
    if (text.size() != 1 || text[0] < '0' || text[0] > '4') {
        error = c.name + ":frames=" + text + " must be 0 to 4 (frames on each side)";
        return false;
    }
    frames = text[0] - '0';
    settings.modifiers.erase("frames");
    return true;
}

template <class Options>
bool stage_and_frames(const Command& c, Options& o, int& frames, std::string& error)
{
    Command settings;
    return frames_of(c, frames, settings, error) && stage_options(settings, o, error);
}

template <class Options>
bool check_with_frames(const Command& c, std::string& error)
{
    Options o;
    int frames;
    return stage_and_frames(c, o, frames, error);
}

std::vector<std::string> with_frames(std::vector<std::string> keys)
{
    keys.push_back("frames");
    return keys;
}

/// The neighbouring frames a cross-frame stage reads, kept alive with the stage.
struct Neighbours {
    std::vector<std::shared_ptr<ImageBuf>> previous, next;
    bool read(const Session& s, int frames, std::string& error)
    {
        return frames == 0 || s.read_neighbours(frames, previous, next, error);
    }
    template <class Options>
    void give_to(Options& o) const
    {
        for (const auto& f : previous)
            o.previous_frames.push_back(f.get());
        for (const auto& f : next)
            o.next_frames.push_back(f.get());
    }
};

bool queue_nfor(Session& s, const Command& c, std::string& error)
{
    mcdn::NforOptions o;
    int frames;
    if (!stage_and_frames(c, o, frames, error))
        return false;
    o.aovs = s.aov_spec;
    o.progress = s.progress();
    s.features_out |= o.features_out;
    // The neighbours are read now and kept with the stage (SURE may run it again).
    Neighbours neighbours;
    if (!neighbours.read(s, frames, error))
        return false;
    neighbours.give_to(o);
    s.queue("nfor", [o, neighbours](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::nfor(dst, src, o, {}, nthreads);
    }, mcdn::stage_reach(o));
    return true;
}

bool queue_cnn(Session& s, const Command& c, std::string& error)
{
    mcdn::CnnOptions o;
    int frames;
    if (!stage_and_frames(c, o, frames, error))
        return false;
    o.aovs = s.aov_spec;
    o.progress = s.progress();
    // Cross-frame: the frames combined (mcdn/frames.h), then the CNN; both are the denoiser
    // (SURE probes this frame through both).
    Neighbours neighbours;
    if (!neighbours.read(s, frames, error))
        return false;
    mcdn::CombineFramesOptions combine;
    combine.aovs = s.aov_spec;
    neighbours.give_to(combine);
    s.queue("cnn", [o, combine, neighbours](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        if (combine.previous_frames.empty() && combine.next_frames.empty())
            return mcdn::cnn(dst, src, o, {}, nthreads);
        return mcdn::denoise_with_frames(dst, src, combine, [&](ImageBuf& d, const ImageBuf& s) {
            return mcdn::cnn(d, s, o, {}, nthreads);
        }, nthreads);
    }, mcdn::stage_reach(o));
    return true;
}

bool run_sure(Session& s, const Command& c, std::string& error)
{
    mcdn::SureOptions o;
    if (!stage_options(c, o, error))
        return false;
    o.aovs = s.aov_spec;
    o.progress = s.progress();
    mcdn::Denoiser denoiser;
    ImageBuf render;
    if (!s.take_denoiser_chain(denoiser, o.denoiser_radius, render, error))
        return false;
    return s.apply_to("sure", render, [&](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::sure(dst, src, denoiser, o, {}, nthreads);
    }, error);
}

bool run_mix(Session& s, const Command& c, std::string& error)
{
    mcdn::MixOptions o;
    if (!stage_options(c, o, error))
        return false;
    o.aovs = s.aov_spec;
    o.progress = s.progress();
    return s.apply("mix", [&](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::mix(dst, src, o, {}, nthreads);
    }, error);
}

// The best chain the inputs allow (mcdn/denoise.h), run as the stage commands would run it.
bool check_denoise(const Command& c, std::string& error)
{
    int frames;
    Command settings;
    return frames_of(c, frames, settings, error);
}

bool run_denoise(Session& s, const Command& c, std::string& error)
{
    if (!s.load(error))
        return false;
    mcdn::DenoisePlan plan;
    if (!mcdn::plan_denoise(plan, s.image().spec(), s.aov_spec, error)) {
        error = "--denoise: " + error;
        return false;
    }
    if (s.verbose)
        std::cerr << "mcdntool: --denoise runs " << plan.describe() << "\n";
    for (const std::string& stage : plan.stages) {
        Command step { "--" + stage, {}, {} };
        if (stage == "mix")
            step.modifiers["model"] = "net";
        if (stage == "cnn" && c.has("frames"))  // cross-frame: the CNN's input combined
            step.modifiers["frames"] = c.modifier("frames");
        const bool ok = stage == "cnn"    ? queue_cnn(s, step, error)
                        : stage == "sure" ? run_sure(s, step, error)
                                          : run_mix(s, step, error);
        if (!ok)
            return false;
    }
    return true;
}

}  // namespace

bool is_stage(const std::string& name)
{
    static const std::vector<CommandInfo> stages = stage_commands();
    return std::any_of(stages.begin(), stages.end(),
                       [&](const CommandInfo& stage) { return stage.name == name; });
}

std::vector<CommandInfo> stage_commands()
{
    return {
        { "--denoise", "", { "frames" },
          "The best chain the inputs allow: with a colour variance --cnn --sure --mix "
          "(KPCN, its SURE, the progressive mix by the network: never much worse than the "
          "better of render and CNN), without one --cnn alone. -v prints which and why. "
          "To choose stages and their settings, name them instead. In a sequence, frames=2 "
          "is cross-frame: the CNN's input is this frame combined with 2 previous and 2 next "
          "ones where they agree (as --cnn:frames=2), against flicker.",
          run_denoise, false, check_denoise,
          "the colour (any preset); with its variance (the renderer's variance AOV, Cycles "
          "via -i:as=variance, a Tungsten folder) the mixed chain. Albedo, normal and depth "
          "help the CNN; missing ones are zero (-v names them)." },
        { "--prefilter", "", mcdn::setting_keys("prefilter"),
          "NFOR feature prefilter (§5.1): NL-means cross-filtering of albedo, normal, depth "
          "and visibility with their half buffers. window=11 patch=7 k=0.5; features=a,b "
          "adds extra feature channels.",
          queue_prefilter, false, check<mcdn::PrefilterOptions>,
          "the features (albedo, normal, depth, visibility) with their half buffers "
          "(-i:as=halfA, -i:as=halfB) and variances; without halves each feature is "
          "filtered by its own variance." },
        { "--nfor", "", with_frames(mcdn::setting_keys("nfor")),
          "NFOR denoiser (§5.2-5.4): first-order regression on the features, collaborative, "
          "bandwidth chosen per pixel. window=19 patch=7 k=0.5,1.0; mse=1 and selection=1 "
          "add nfor.mse.* and nfor.selection.* channels. Prefilters the features itself "
          "unless --prefilter ran. Extra AOVs (light groups, extra.NAME) are denoised with "
          "the beauty's weights so they still add up (extras=0: keep them as they are). "
          "A pixel holding one sample worth a hundred of its neighbours (a caustic through "
          "glass, a firefly) is kept out of the regressions and its excess removed, as a "
          "sample clamp would (outliers=drop; keep: added back where it was; off: left in). "
          "Safety net (on; fallback=0: off): a 32x32 tile where NFOR's own MSE estimate is "
          "above the render's variance is the render, -v says how many (fallback-aov=1 adds "
          "channel nfor.fallback, 1 on those tiles). "
          "Cross-frame (§8), in a sequence: frames=2 fits over the 2 previous and 2 next "
          "frames too, aligned by the motion vectors (Blender's Vector pass); it reads them "
          "(also across --frames chunk edges), never writes them, and runs the whole frame.",
          queue_nfor, false, check_with_frames<mcdn::NforOptions>,
          "the colour and its two half buffers (each the mean of half the samples: "
          "-i:as=halfA, -i:as=halfB; a Tungsten folder has them); the variance of the mean "
          "(else the halves' difference); features, prefiltered unless --prefilter ran. "
          "Without halves, render them, or use --denoise or --cnn." },
        { "--cnn", "", with_frames(mcdn::setting_keys("cnn")),
          "Kernel-predicting CNN denoiser (KPCN): diffuse/specular split, our trained weights "
          "(models/kpcn.mcdnw; weights=FILE), tiled (tile=384). Extra AOVs take their share "
          "of the beauty's denoised light through its kernels (extras=0: keep them). A pixel "
          "holding one sample worth a hundred of its neighbours (a caustic through glass, a "
          "firefly) is taken out of the network's input and its excess removed, by --nfor's "
          "rule (outliers=drop; off: left in, where the kernels spread it). "
          "Cross-frame, in a sequence: frames=2 first combines this frame with 2 previous "
          "and 2 next ones, aligned by the motion vectors (Blender's Vector pass), weighted "
          "by how well their patches agree: a render of up to 5 times the samples where "
          "they do. It reads them (also across --frames chunk edges), never writes them.",
          queue_cnn, false, check_with_frames<mcdn::CnnOptions>,
          "the colour; the diffuse/specular split (Cycles' DiffCol/Dir/Ind and Gloss*, or "
          "diffuse.*, specular.*) where present; albedo, normal, depth and their variances "
          "(missing ones are zero: -v names them)." },
        { "--sure", "", mcdn::setting_keys("sure"),
          "Monte-Carlo SURE of the denoisers before it (PD §3.2): adds sure.*, "
          "sure.divergence.*, sure.residual.* and noisy.* channels. probes=1 (K; costs K+1 "
          "denoiser runs), eps=1e-3 (relative probe step). -v says in how many 32x32 tiles SURE "
          "finds the denoiser worse than the render, and those tiles are the render (safety net, "
          "for any denoiser; fallback=0: the denoiser's are kept); fallback-aov=1 adds channel "
          "sure.fallback, 1 on those tiles.",
          run_sure, false, check<mcdn::SureOptions>,
          "the colour and the variance of its mean, and a denoiser before it (--cnn, --nfor, "
          "--prefilter --nfor), which it runs probes+1 times." },
        { "--mix", "", mcdn::setting_keys("mix"),
          "Progressive mix of the render and the denoised image (PD §4), after --sure: "
          "model=net|analytic (default net), ttest=1 bounds alpha by the t-test (eq. 18), "
          "alpha=1 adds "
          "mix.alpha.* channels; with model=net: the network trained for the denoiser before "
          "--sure (models/mix_cnn.mcdnw after --cnn, else models/mix.mcdnw; weights=FILE), "
          "afloor=1, alpha is at least the analytic model's; with either model: "
          "outlier=0.3, alpha is at least eq. 9 where the "
          "render's variance exceeds 0.3 (y^2 + 0.01), drop=1.5: alpha = 1 where it exceeds "
          "1.5 (y^2 + 0.01) (0: off).",
          run_mix, false, check<mcdn::MixOptions>,
          "what --sure adds (sure.*, noisy.*): give --sure first; the colour's variance." },
    };
}

}  // namespace mcdntool
