// Stage options from text settings (mcdn/settings.h).
#include "mcdn/settings.h"

#include "mcdn/stages.h"

#include "chain/chain_steps.h"
#include "chain/settings_reader.h"
#include "core/attributes.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <OpenImageIO/strutil.h>

namespace mcdn {

using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

bool parse_finite(const std::string& text, double& value)
{
    if (!Strutil::string_is_float(text))
        return false;
    value = Strutil::stod(text);
    return std::abs(value) <= std::numeric_limits<float>::max();  // false for nan too
}

namespace {

// "0.5,1.0": NFOR's two candidate bandwidths (the op rejects k <= 0); k is set only when valid.
bool parse_bandwidths(const std::string& text, std::array<float, 2>& k)
{
    auto parts = Strutil::splits(text, ",");
    double k0 = 0, k1 = 0;
    if (parts.size() != 2 || !parse_finite(parts[0], k0) || !parse_finite(parts[1], k1))
        return false;
    k = { float(k0), float(k1) };
    return true;
}

// Digits only: std::stoull would throw on "abc" and wrap "-1" around.
bool parse_seed(const std::string& text, uint64_t& seed)
{
    if (text.empty() || text.size() > 19
        || text.find_first_not_of("0123456789") != std::string::npos)
        return false;
    seed = std::stoull(text);
    return true;
}

}  // namespace

const std::vector<std::string>& setting_keys(const std::string& stage)
{
    static const std::vector<std::string> none;
    const StageInfo* info = find_stage(stage);
    return info ? info->keys : none;
}

bool apply_settings(PrefilterOptions& o, const Settings& s, std::string& error)
{
    return SettingsReader(s, "prefilter", error)
        .width("window", o.window_radius)
        .width("patch", o.patch_radius)
        .number("k", o.k)
        .list("features", o.extra_features)
        .flag("features-out", o.features_out)
        .skip(o.skip)
        .ok();
}

bool apply_settings(NforOptions& o, const Settings& s, std::string& error)
{
    bool ok = SettingsReader(s, "nfor", error)
                  .width("window", o.window_radius)
                  .width("patch", o.patch_radius)
                  .custom("k", "must be two bandwidths, e.g. k=0.5,1.0",
                          [&](const std::string& v) { return parse_bandwidths(v, o.candidate_k); })
                  .flag("mse", o.output_mse)
                  .flag("selection", o.output_selection)
                  .flag("fallback", o.fallback)
                  .flag("fallback-aov", o.output_fallback)
                  .flag("extras", o.denoise_extras)
                  .list("features", o.extra_features)
                  .flag("features-out", o.features_out)
                  .flag("halves", o.use_halves)
                  .custom("outliers", "must be keep, drop or off",
                          [&](const std::string& v) {
                              if (v == "keep")
                                  o.outliers = NforOptions::Outliers::Keep;
                              else if (v == "drop")
                                  o.outliers = NforOptions::Outliers::Drop;
                              else if (v == "off" || v == "0")
                                  o.outliers = NforOptions::Outliers::Off;
                              else
                                  return false;
                              return true;
                          })
                  .skip(o.skip)
                  .ok();
    // The second pass (§5.4) filters with the first pass's window.
    o.second_window_radius = o.window_radius;
    return ok;
}

bool apply_settings(CnnOptions& o, const Settings& s, std::string& error)
{
    return SettingsReader(s, "cnn", error)
        .text("weights", o.weights)
        .positive_int("tile", o.tile_size)
        .flag("extras", o.denoise_extras)
        .drop_or_off("outliers", o.outliers)
        .skip(o.skip)
        .ok();
}

bool apply_settings(SureOptions& o, const Settings& s, std::string& error)
{
    return SettingsReader(s, "sure", error)
        .positive_int("probes", o.probes)
        .custom("eps", "must be a number above 0 and at most 0.1 (relative to the mean |x|)",
                [&](const std::string& v) {
                    // Checked as the float the op gets: 1e-63 is 0 there.
                    double d;
                    if (!parse_finite(v, d))
                        return false;
                    const float eps = float(d);
                    if (!(eps > 0) || eps > kMaxEpsilonRelative)
                        return false;
                    o.epsilon_relative = eps;
                    return true;
                })
        .custom("seed", "is not a whole number below 10^19",
                [&](const std::string& v) { return parse_seed(v, o.seed); })
        .flag("fallback", o.fallback)
        .flag("fallback-aov", o.output_fallback)
        .skip(o.skip)
        .ok();
}

bool apply_settings(MixOptions& o, const Settings& s, std::string& error)
{
    return SettingsReader(s, "mix", error)
        .custom("model", "is not net or analytic",
                [&](const std::string& v) {
                    if (v != "net" && v != "analytic")
                        return false;
                    o.model = v == "net" ? MixOptions::Model::Net : MixOptions::Model::Analytic;
                    return true;
                })
        .text("weights", o.weights)
        .flag("ttest", o.t_test)
        .flag("alpha", o.output_alpha)
        .number("outlier", o.outlier_relative_variance)
        .flag("afloor", o.analytic_floor)
        .number("drop", o.drop_relative_variance)
        .skip(o.skip)
        .ok();
}

Settings stage_settings(const std::map<std::string, std::string>& all, const std::string& stage)
{
    Settings settings;
    const std::string prefix = stage + ".";
    for (const auto& [key, value] : all)
        if (Strutil::starts_with(key, prefix))
            settings[key.substr(prefix.size())] = value;
    return settings;
}

namespace {

Denoiser composed(std::vector<std::pair<std::string, Denoiser>> stages, bool in_place)
{
    return [stages = std::move(stages), in_place](ImageBuf& dst, const ImageBuf& src) {
        // Each stage reads the one before's result; the first reads src itself (a copy of
        // the frame per call would be SURE's largest cost after the denoiser's own).
        const ImageBuf* input = &src;
        ImageBuf current;
        const bool color_only = src.spec().get_int_attribute(kColorOnlyAttribute, 0) == 1;
        if (in_place && &dst == &src && !stages.empty()) {  // the first stage in it too
            current = std::move(dst);
            input = &current;
        }
        for (size_t i = 0; i < stages.size(); ++i) {
            const auto& [name, stage] = stages[i];
            const bool last = i + 1 == stages.size();
            ImageBuf next;
            // In place on the one before's result, which nothing else reads (never
            // colour-only: only the last stage is asked for that).
            const bool here = in_place && input == &current;
            bool ok;
            if (here) {
                ok = stage(current, current);
                next = std::move(current);  // its error too
                current = ImageBuf();
            } else {
                ok = stage(next, *input);
            }
            if (ok && !last && !here && next.nchannels() < input->nchannels()) {
                // A colour-only result (kColourOnlyAttribute) where the next stage needs the
                // frame: run again without the mark.
                ImageBuf unmarked = *input;
                unmarked.specmod().erase_attribute(kColorOnlyAttribute);
                next = ImageBuf();
                ok = stage(next, unmarked);
            }
            if (!ok) {
                dst.errorfmt("{}", stage_error(name, next.geterror()));
                return false;
            }
            current = std::move(next);
            if (color_only && i + 2 == stages.size())
                current.specmod().attribute(kColorOnlyAttribute, 1);
            else
                current.specmod().erase_attribute(kColorOnlyAttribute);
            input = &current;
        }
        if (stages.empty())
            current = src;
        dst = std::move(current);
        return true;
    };
}

}  // namespace

Denoiser compose(std::vector<std::pair<std::string, Denoiser>> stages)
{
    return composed(std::move(stages), false);
}

Denoiser compose_in_place(std::vector<std::pair<std::string, Denoiser>> stages)
{
    return composed(std::move(stages), true);
}

}  // namespace mcdn
