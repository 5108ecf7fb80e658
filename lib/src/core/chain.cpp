// Running stages by name (mcdn/chain.h).
#include "mcdn/chain.h"

#include <algorithm>

#include <OpenImageIO/strutil.h>

#include "mcdn/cnn.h"
#include "mcdn/mix.h"
#include "mcdn/nfor.h"
#include "mcdn/prefilter.h"
#include "mcdn/sure.h"

namespace mcdn {

using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

namespace {

const std::vector<std::string> kStages = { "prefilter", "nfor", "cnn", "sure", "mix" };

std::string setting(const ChainOptions& o, const std::string& key, const std::string& fallback)
{
    auto it = o.settings.find(key);
    return it == o.settings.end() ? fallback : it->second;
}

// A width setting (odd pixels) as a radius, or the default radius.
int radius(const ChainOptions& o, const std::string& key, int fallback)
{
    std::string value = setting(o, key, "");
    return value.empty() ? fallback : std::max(0, Strutil::stoi(value) / 2);
}

// "STAGE.skip=0" turns the stage's skipping off, "STAGE.converged=X" is its threshold.
SkipOptions skip_setting(const ChainOptions& o, const std::string& stage)
{
    SkipOptions s;
    s.enabled = setting(o, stage + ".skip", "1") != "0";
    s.max_relative_error = Strutil::stof(setting(o, stage + ".converged",
                                                 std::to_string(s.max_relative_error)));
    return s;
}

Denoiser denoiser_stage(const std::string& name, const ChainOptions& o, int nthreads)
{
    if (name == "prefilter") {
        PrefilterOptions p;
        p.aovs = o.aovs;
        p.window_radius = radius(o, "prefilter.window", p.window_radius);
        p.patch_radius = radius(o, "prefilter.patch", p.patch_radius);
        p.k = Strutil::stof(setting(o, "prefilter.k", std::to_string(p.k)));
        p.skip = skip_setting(o, "prefilter");
        return [p, nthreads](ImageBuf& dst, const ImageBuf& src) {
            return prefilter(dst, src, p, {}, nthreads);
        };
    }
    if (name == "cnn") {
        CnnOptions c;
        c.aovs = o.aovs;
        c.weights = setting(o, "cnn.weights", "");
        c.denoise_extras = setting(o, "cnn.extras", "1") != "0";
        c.skip = skip_setting(o, "cnn");
        return [c, nthreads](ImageBuf& dst, const ImageBuf& src) { return cnn(dst, src, c, {}, nthreads); };
    }
    NforOptions n;
    n.aovs = n.prefilter.aovs = o.aovs;
    n.window_radius = n.second_window_radius = radius(o, "nfor.window", n.window_radius);
    n.patch_radius = radius(o, "nfor.patch", n.patch_radius);
    n.output_mse = setting(o, "nfor.mse", "0") == "1";
    n.output_selection = setting(o, "nfor.selection", "0") == "1";
    n.denoise_extras = setting(o, "nfor.extras", "1") != "0";
    n.skip = skip_setting(o, "nfor");
    return [n, nthreads](ImageBuf& dst, const ImageBuf& src) { return nfor(dst, src, n, {}, nthreads); };
}

}  // namespace

bool parse_chain(std::vector<std::string>& stages, const std::string& text, std::string& error)
{
    stages = Strutil::splits(text, ",");
    bool seen_sure = false;
    for (const auto& s : stages) {
        if (std::find(kStages.begin(), kStages.end(), s) == kStages.end()) {
            error = format("unknown stage '{}' in chain '{}' (stages: {})", s, text,
                           Strutil::join(kStages, ", "));
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

bool run_chain(ImageBuf& dst, const ImageBuf& src, const ChainOptions& o, ROI roi, int nthreads)
{
    std::vector<std::string> check;
    std::string error;
    if (!parse_chain(check, Strutil::join(o.stages, ","), error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    ImageBuf current = src;
    std::vector<Denoiser> pending;  // denoisers since the last sure/mix
    auto compose = [](std::vector<Denoiser> stages) -> Denoiser {
        return [stages](ImageBuf& out, const ImageBuf& in) {
            ImageBuf x = in;
            for (const auto& stage : stages) {
                ImageBuf next;
                if (!stage(next, x)) {
                    out.errorfmt("{}", next.geterror());
                    return false;
                }
                x = std::move(next);
            }
            out = std::move(x);
            return true;
        };
    };
    for (size_t i = 0; i < o.stages.size(); ++i) {
        const std::string& name = o.stages[i];
        ImageBuf next;
        bool ok = true;
        if (name == "prefilter" || name == "nfor" || name == "cnn") {
            // Denoisers wait: a sure after them runs them itself (K + 1 times), else they
            // run at the end.
            pending.push_back(denoiser_stage(name, o, nthreads));
            continue;
        }
        if (name == "sure") {
            SureOptions s;
            s.aovs = o.aovs;
            s.probes = Strutil::stoi(setting(o, "sure.probes", "1"));
            s.epsilon_relative = Strutil::stof(setting(o, "sure.eps", "0.001"));
            s.skip = skip_setting(o, "sure");
            ok = sure(next, current, compose(pending), s, roi, nthreads);
            pending.clear();
        } else {  // mix
            MixOptions m;
            m.aovs = o.aovs;
            m.model = setting(o, "mix.model", "analytic") == "net" ? MixOptions::Model::Net
                                                                   : MixOptions::Model::Analytic;
            m.weights = setting(o, "mix.weights", "");
            m.t_test = setting(o, "mix.ttest", "1") != "0";
            m.output_alpha = setting(o, "mix.alpha", "0") == "1";
            m.skip = skip_setting(o, "mix");
            ok = mix(next, current, m, roi, nthreads);
        }
        if (!ok) {
            dst.errorfmt("{}: {}", name, next.geterror());
            return false;
        }
        current = std::move(next);
    }
    if (!pending.empty() && !compose(pending)(dst, current))
        return false;
    if (pending.empty())
        dst = std::move(current);
    return true;
}

}  // namespace mcdn
