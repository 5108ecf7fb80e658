// The denoising stages as mcdntool commands: each maps its modifiers onto the stage's
// Options. Denoisers (--prefilter, --nfor) queue up; the next command that needs pixels runs
// them, and --sure takes the queued chain as the denoiser whose error it estimates.
#include <OpenImageIO/strutil.h>

#include "mcdn/cnn.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/sure.h"

#include "session.h"

namespace mcdntool {

using OIIO::ImageBuf;
using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

namespace {

// A window or patch given as its width (odd, like the papers: 19x19) -> radius.
bool width_to_radius(const Command& c, const std::string& key, int& radius, std::string& error)
{
    if (!c.has(key))
        return true;
    int width = Strutil::stoi(c.modifier(key));
    if (width < 1 || width % 2 == 0 || width > 101) {
        error = format("{}:{}={} must be an odd width between 1 and 101", c.name, key, c.modifier(key));
        return false;
    }
    radius = (width - 1) / 2;
    return true;
}

bool read_float(const Command& c, const std::string& key, float& value, std::string& error)
{
    double number = value;
    if (!c.number(key, number, error))
        return false;
    value = float(number);
    return true;
}

std::vector<std::string> features_of(const Command& c)
{
    return c.has("features") ? Strutil::splits(c.modifier("features"), ",")
                             : std::vector<std::string>();
}

bool read_positive_int(const Command& c, const std::string& key, int& value, std::string& error)
{
    if (!c.has(key))
        return true;
    if (!Strutil::string_is<int>(c.modifier(key)) || Strutil::stoi(c.modifier(key)) < 1) {
        error = format("{}:{}={} is not a positive whole number", c.name, key, c.modifier(key));
        return false;
    }
    value = Strutil::stoi(c.modifier(key));
    return true;
}

// :skip=0 turns the stage's skipping off, :converged=X sets its threshold (mcdn/skip.h).
bool skip_options(const Command& c, mcdn::SkipOptions& o, std::string& error)
{
    const std::string skip = c.modifier("skip", "1");
    if (skip != "0" && skip != "1") {
        error = format("{}:skip={} must be 0 or 1", c.name, skip);
        return false;
    }
    o.enabled = skip == "1";
    if (!read_float(c, "converged", o.max_relative_error, error))
        return false;
    if (!(o.max_relative_error >= 0)) {
        error = format("{}:converged={} must be >= 0 (a relative standard error)", c.name,
                       c.modifier("converged"));
        return false;
    }
    return true;
}

// The stages' Options from their modifiers (the AOV spec is the session's); no side effects,
// so the same functions check the command line before anything runs.
bool prefilter_options(const Command& c, mcdn::PrefilterOptions& o, std::string& error)
{
    o.extra_features = features_of(c);
    return width_to_radius(c, "window", o.window_radius, error)
           && width_to_radius(c, "patch", o.patch_radius, error) && read_float(c, "k", o.k, error)
           && skip_options(c, o.skip, error);
}

bool nfor_options(const Command& c, mcdn::NforOptions& o, std::string& error)
{
    o.extra_features = features_of(c);
    o.output_mse = c.modifier("mse", "0") == "1";
    o.output_selection = c.modifier("selection", "0") == "1";
    o.denoise_extras = c.modifier("extras", "1") != "0";
    if (!skip_options(c, o.skip, error) || !width_to_radius(c, "window", o.window_radius, error)
        || !width_to_radius(c, "patch", o.patch_radius, error))
        return false;
    if (c.has("k")) {
        auto ks = Strutil::splits(c.modifier("k"), ",");
        double k0 = 0, k1 = 0;
        if (ks.size() != 2 || !parse_finite(ks[0], k0) || !parse_finite(ks[1], k1)) {
            error = format("--nfor:k={} must be two bandwidths, e.g. k=0.5,1.0", c.modifier("k"));
            return false;
        }
        o.candidate_k = { float(k0), float(k1) };  // the op rejects k <= 0
    }
    o.second_window_radius = o.window_radius;
    return true;
}

bool cnn_options(const Command& c, mcdn::CnnOptions& o, std::string& error)
{
    if (c.has("weights"))
        o.weights = c.modifier("weights");
    o.denoise_extras = c.modifier("extras", "1") != "0";
    return read_positive_int(c, "tile", o.tile_size, error) && skip_options(c, o.skip, error);
}

bool sure_options(const Command& c, mcdn::SureOptions& o, std::string& error)
{
    if (!read_positive_int(c, "probes", o.probes, error)
        || !read_float(c, "eps", o.epsilon_relative, error) || !skip_options(c, o.skip, error))
        return false;
    if (c.has("seed")) {
        // std::stoull would throw on "abc" and wrap "-1" around: accept digits only.
        const std::string seed = c.modifier("seed");
        if (seed.empty() || seed.size() > 19 || seed.find_first_not_of("0123456789") != std::string::npos) {
            error = format("--sure:seed={} is not a whole number below 10^19", seed);
            return false;
        }
        o.seed = std::stoull(seed);
    }
    return true;
}

bool mix_options(const Command& c, mcdn::MixOptions& o, std::string& error)
{
    std::string model = c.modifier("model", "analytic");
    if (model == "net")
        o.model = mcdn::MixOptions::Model::Net;
    else if (model != "analytic") {
        error = format("--mix:model={} is not net or analytic", model);
        return false;
    }
    o.weights = c.modifier("weights");
    o.t_test = c.modifier("ttest", "1") != "0";
    o.output_alpha = c.modifier("alpha", "0") == "1";
    return skip_options(c, o.skip, error);
}

// A check is the options function with the result thrown away.
template <class Options, bool (*parse)(const Command&, Options&, std::string&)>
bool check(const Command& c, std::string& error)
{
    Options o;
    return parse(c, o, error);
}

bool queue_prefilter(Session& s, const Command& c, std::string& error)
{
    mcdn::PrefilterOptions o;
    if (!prefilter_options(c, o, error))
        return false;
    o.aovs = s.aov_spec;
    s.queue("prefilter", [o](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::prefilter(dst, src, o, {}, nthreads);
    });
    return true;
}

bool queue_nfor(Session& s, const Command& c, std::string& error)
{
    mcdn::NforOptions o;
    if (!nfor_options(c, o, error))
        return false;
    o.aovs = o.prefilter.aovs = s.aov_spec;
    s.queue("nfor", [o](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::nfor(dst, src, o, {}, nthreads);
    });
    return true;
}

bool queue_cnn(Session& s, const Command& c, std::string& error)
{
    mcdn::CnnOptions o;
    if (!cnn_options(c, o, error))
        return false;
    o.aovs = s.aov_spec;
    s.queue("cnn", [o](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::cnn(dst, src, o, {}, nthreads);
    });
    return true;
}

bool run_sure(Session& s, const Command& c, std::string& error)
{
    mcdn::SureOptions o;
    if (!sure_options(c, o, error))
        return false;
    o.aovs = s.aov_spec;
    mcdn::Denoiser denoiser;
    ImageBuf render;
    if (!s.take_denoiser_chain(denoiser, render, error))
        return false;
    return s.apply_to("sure", render, [&](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::sure(dst, src, denoiser, o, {}, nthreads);
    }, error);
}

bool run_mix(Session& s, const Command& c, std::string& error)
{
    mcdn::MixOptions o;
    if (!mix_options(c, o, error))
        return false;
    o.aovs = s.aov_spec;
    return s.apply("mix", [&](ImageBuf& dst, const ImageBuf& src, int nthreads) {
        return mcdn::mix(dst, src, o, {}, nthreads);
    }, error);
}

}  // namespace

std::vector<CommandInfo> stage_commands()
{
    return {
        { "--prefilter", "", { "window", "patch", "k", "features", "skip", "converged" },
          "NFOR feature prefilter (§5.1): NL-means cross-filtering of albedo, normal, depth "
          "and visibility with their half buffers. window=11 patch=7 k=0.5; features=a,b "
          "adds extra feature channels.",
          queue_prefilter, false, check<mcdn::PrefilterOptions, prefilter_options> },
        { "--nfor", "", { "window", "patch", "k", "mse", "selection", "features", "extras", "skip", "converged" },
          "NFOR denoiser (§5.2-5.4): first-order regression on the features, collaborative, "
          "bandwidth chosen per pixel. window=19 patch=7 k=0.5,1.0; mse=1 and selection=1 "
          "add nfor.mse.* and nfor.selection.* channels. Prefilters the features itself "
          "unless --prefilter ran. Extra AOVs (light groups, extra.NAME) are denoised with "
          "the beauty's weights so they still add up (extras=0: keep them as they are).",
          queue_nfor, false, check<mcdn::NforOptions, nfor_options> },
        { "--cnn", "", { "weights", "tile", "extras", "skip", "converged" },
          "Kernel-predicting CNN denoiser (KPCN): diffuse/specular split, our trained weights "
          "(models/kpcn.mcdnw; weights=FILE), tiled (tile=256). Extra AOVs take their share "
          "of the beauty's denoised light through its kernels (extras=0: keep them).",
          queue_cnn, false, check<mcdn::CnnOptions, cnn_options> },
        { "--sure", "", { "probes", "eps", "seed", "skip", "converged" },
          "Monte-Carlo SURE of the denoisers before it (PD §3.2): adds sure.*, "
          "sure.divergence.*, sure.residual.* and noisy.* channels. probes=1 (K; costs K+1 "
          "denoiser runs), eps=1e-3 (relative probe step).",
          run_sure, false, check<mcdn::SureOptions, sure_options> },
        { "--mix", "", { "model", "weights", "ttest", "alpha", "skip", "converged" },
          "Progressive mix of the render and the denoised image (PD §4), after --sure: "
          "model=analytic|net, ttest=1 bounds alpha by the t-test (eq. 18), alpha=1 adds "
          "mix.alpha.* channels.",
          run_mix, false, check<mcdn::MixOptions, mix_options> },
        // Every stage also takes skip=0|1 and converged=0.08 (mcdn/skip.h): converged tiles
        // pass through untouched, constant features are dropped; skip=0 turns that off.
    };
}

}  // namespace mcdntool
