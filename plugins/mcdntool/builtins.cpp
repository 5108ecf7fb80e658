// The built-in commands of mcdntool: inputs, AOVs, info, metrics, heatmaps, output, fixnan
// (session.h); the session they work on is session.cpp's.

#include "session.h"

#include <algorithm>
#include <cmath>
#include <iostream>
#include <tuple>

#include <fnmatch.h>
#include <unistd.h>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>
#include <OpenImageIO/timer.h>

#include "mcdn/chain.h"
#include "mcdn/color.h"
#include "mcdn/denoise.h"
#include "mcdn/metrics.h"
#include "mcdn/nfor.h"
#include "mcdn/sure.h"
#include "mcdn/settings.h"
#include "mcdn/skip.h"

namespace mcdntool {

using mcdn::Role;
using OIIO::ImageBuf;
using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

namespace {

// -i:as=seed: one of K renders of the frame with different seeds (mcdn::combine_seeds).
bool input_kind_of(const Command& c, mcdn::InputKind& kind, bool& seed, std::string& error)
{
    seed = c.modifier("as") == "seed";
    auto named = mcdn::input_kind_from_name(seed ? "mean" : c.modifier("as", "mean"));
    if (!named) {
        error =
            format("-i:as={} is not one of mean, variance, halfA, halfB, seed", c.modifier("as"));
        return false;
    }
    if (seed && c.has("part")) {
        error = format("-i:as=seed:part={}: a seed is read whole", c.modifier("part"));
        return false;
    }
    kind = *named;
    return true;
}

}  // namespace

bool input_file_of(const Command& c, mcdn::InputFile& file, std::string& error)
{
    mcdn::InputKind kind;
    bool seed = false;
    if (!input_kind_of(c, kind, seed, error))
        return false;
    file = { c.args[0], kind, c.modifier("part") };
    if (seed)
        file.seeds = { c.args[0] };
    return true;
}

void add_input(std::vector<mcdn::InputFile>& inputs, const mcdn::InputFile& file)
{
    if (!file.seeds.empty() && !inputs.empty() && !inputs.back().seeds.empty())
        inputs.back().seeds.push_back(file.path);
    else
        inputs.push_back(file);
}

namespace {

bool metrics_format_of(const Command& c, bool& json, std::string& error)
{
    std::string fmt = c.modifier("format", "text");
    if (fmt != "text" && fmt != "json") {
        error = format("--metrics:format={} is not text or json", fmt);
        return false;
    }
    json = fmt == "json";
    return true;
}

struct HeatmapSettings {
    mcdn::ErrorKind kind;
    double log10_min, log10_max;
};

bool heatmap_settings_of(const Command& c, HeatmapSettings& settings, std::string& error)
{
    static const std::map<std::string, mcdn::ErrorKind> kinds = {
        { "relmse", mcdn::ErrorKind::RelMSE },
        { "se", mcdn::ErrorKind::SquaredError },
        { "ae", mcdn::ErrorKind::AbsoluteError },
        { "smape", mcdn::ErrorKind::SMAPE }
    };
    auto kind = kinds.find(c.modifier("metric", "relmse"));
    if (kind == kinds.end()) {
        error = format("--heatmap:metric={} is not relmse, se, ae or smape", c.modifier("metric"));
        return false;
    }
    settings.kind = kind->second;
    settings.log10_min = -4;
    settings.log10_max = 0;
    return c.number("min", settings.log10_min, error) && c.number("max", settings.log10_max, error);
}

}  // namespace

bool write_options_of(const Command& c, mcdn::WriteOptions& options, std::string& error)
{
    // Unless given: each channel's type and the compression as the input had them.
    const std::string datatype = c.modifier("datatype", "");
    if (datatype == "half")
        options.datatype = OIIO::TypeDesc::HALF;
    else if (datatype == "float")
        options.datatype = OIIO::TypeDesc::FLOAT;
    else if (!datatype.empty()) {
        error = format("-o:datatype={} is not half or float", datatype);
        return false;
    }
    options.compression = c.modifier("compression", "");
    if (!mcdn::check_compression(options.compression, error)) {
        error = "-o:" + error;
        return false;
    }
    return true;
}

bool check_input(const Command& c, std::string& error)
{
    mcdn::InputKind kind;
    bool seed = false;
    return input_kind_of(c, kind, seed, error);
}

bool check_aov(const Command& c, std::string& error)
{
    mcdn::AovSpec spec;
    for (const auto& token : c.args)
        if (!spec.parse_override(token, error))
            return false;
    return true;
}

bool check_metrics(const Command& c, std::string& error)
{
    bool json;
    return metrics_format_of(c, json, error);
}

bool check_heatmap(const Command& c, std::string& error)
{
    HeatmapSettings settings;
    return heatmap_settings_of(c, settings, error);
}

bool check_output(const Command& c, std::string& error)
{
    mcdn::WriteOptions options;
    return write_options_of(c, options, error);
}

bool run_input(Session& s, const Command& c, std::string& error)
{
    mcdn::InputFile file;
    if (!input_file_of(c, file, error))
        return false;
    add_input(s.inputs, file);
    s.invalidate();
    return true;
}

bool run_aov(Session& s, const Command& c, std::string& error)
{
    if (c.has("preset"))
        s.aov_spec.preset = c.modifier("preset");
    if (c.has("layer"))
        s.aov_spec.layer = c.modifier("layer");
    if (c.has("colorspace"))
        s.aov_spec.colorspace = c.modifier("colorspace");
    for (const auto& token : c.args)
        if (!s.aov_spec.parse_override(token, error))
            return false;
    s.invalidate();
    return true;
}

bool run_channels(Session& s, const Command& c, std::string& error)
{
    s.output_channels = Strutil::splits(c.args[0], ",");
    return true;
}

bool run_info(Session& s, const Command& c, std::string& error)
{
    if (!s.load(error))
        return false;
    const auto& spec = s.image().spec();
    std::cout << format("{}: {} x {}, {} channels from {} input(s), AOV preset '{}'\n",
                        s.inputs[0].path, spec.width, spec.height, spec.nchannels, s.inputs.size(),
                        s.aovs().preset());
    for (int r = 0; r < mcdn::kRoleCount; ++r) {
        Role role = Role(r);
        if (s.aovs().has(role))
            std::cout << format(
                "  {:<20} {}{}\n", mcdn::role_name(role), Strutil::join(s.aovs().names(role), ", "),
                role == Role::Color && s.aovs().grey() ? " (luminance only: denoised as grey)"
                                                       : "");
    }
    for (const auto& extra : s.aovs().extras()) {
        std::vector<std::string> factor;
        for (int ch : extra.factor)
            factor.push_back(spec.channelnames[size_t(ch)]);
        std::cout << format("  extra {:<14} {}{}\n", extra.name, Strutil::join(extra.names, ", "),
                            factor.empty() ? std::string()
                                           : " (denoised as light: x "
                                                 + factor[0].substr(0, factor[0].rfind('.')) + ")");
    }
    if (!s.aovs().detected_because().empty())
        std::cout << "  preset detected from " << s.aovs().detected_because() << "\n";
    std::cout << "  stages:\n";
    for (const std::string& stage : mcdn::stage_names(
             { mcdn::StageKind::Denoiser, mcdn::StageKind::Estimator, mcdn::StageKind::Mixer })) {
        std::string how;
        const bool can = mcdn::stage_can_run(stage, s.aovs(), how);
        std::cout << format("    --{:<10} {}: {}\n", stage, can ? "yes" : "no ", how);
    }
    mcdn::DenoisePlan plan;
    if (mcdn::plan_denoise(plan, spec, s.aov_spec, error))
        std::cout << "    --denoise    runs " << plan.describe() << "\n";
    if (s.aovs().has(Role::ColorVariance)) {
        const mcdn::SkipOptions skip;
        const mcdn::ConvergedCount converged =
            mcdn::count_converged_tiles(s.image(), s.aovs(), skip);
        std::cout << format("  converged tiles: {} of {} ({:.0f}%) at :converged={:g}, passed "
                            "through by every stage\n",
                            converged.converged, converged.tiles,
                            100.0 * converged.converged / std::max(converged.tiles, 1),
                            skip.max_relative_error);
    }
    if (c.has("verbose"))
        std::cout << "  channels: " << Strutil::join(spec.channelnames, ", ") << "\n";
    return true;
}

namespace {

// The reference's colour channels: the AOV preset's colour role if the reference has it,
// else R,G,B, else its first three channels.
std::vector<int> reference_color(const ImageBuf& reference, const mcdn::AovSpec& spec)
{
    mcdn::AovSet set;
    std::string ignored;
    if (mcdn::resolve_aovs(set, spec, reference.spec(), ignored) && set.has(Role::Color))
        return set.channels(Role::Color);
    const auto& rs = reference.spec();
    if (rs.channelindex("R") >= 0 && rs.channelindex("G") >= 0 && rs.channelindex("B") >= 0)
        return { rs.channelindex("R"), rs.channelindex("G"), rs.channelindex("B") };
    return { 0, 1, 2 };
}

// Reads a reference and fills the channel lists a metric compares.
bool prepare_comparison(Session& s, const std::string& ref_path, const std::string& channels,
                        ImageBuf& reference, mcdn::MetricsOptions& options, std::string& error)
{
    if (!s.load(error))
        return false;
    if (!mcdn::read_image(reference, ref_path)) {
        error = reference.geterror();
        return false;
    }
    const auto& spec = s.image().spec();
    if (channels.empty()) {
        options.image_channels = s.aovs().channels(Role::Color);
        options.reference_channels = reference_color(reference, s.aov_spec);
    } else {
        options.image_channels.clear();
        options.reference_channels.clear();
        for (const auto& name : Strutil::splits(channels, ",")) {
            int ic = spec.channelindex(name), rc = reference.spec().channelindex(name);
            if (ic < 0 || rc < 0) {
                error =
                    format("{}: channel '{}' is not in {}", ic < 0 ? s.inputs[0].path : ref_path,
                           name, ic < 0 ? "the image" : "the reference");
                return false;
            }
            options.image_channels.push_back(ic);
            options.reference_channels.push_back(rc);
        }
    }
    if (reference.spec().nchannels < 3 && channels.empty()) {
        error = format("{}: reference has {} channel(s), needs RGB", ref_path,
                       reference.spec().nchannels);
        return false;
    }
    return true;
}

}  // namespace

bool run_metrics(Session& s, const Command& c, std::string& error)
{
    ImageBuf reference;
    mcdn::MetricsOptions options;
    if (!prepare_comparison(s, c.args[0], c.modifier("channels"), reference, options, error))
        return false;
    options.trim = Strutil::stoi(c.modifier("trim", "0")) != 0;
    bool json = false;
    if (!metrics_format_of(c, json, error))
        return false;
    mcdn::Metrics m;
    if (!mcdn::compute_metrics(m, s.image(), reference, options, error, {}, s.nthreads)) {
        error = format("{}: {}", c.args[0], error);
        return false;
    }
    std::cout << mcdn::format_metrics(m, json) << (json ? "\n" : "") << std::flush;
    s.last_reference = c.args[0];
    return true;
}

bool run_heatmap(Session& s, const Command& c, std::string& error)
{
    std::string ref_path = c.modifier("ref", s.last_reference);
    if (ref_path.empty()) {
        error = "--heatmap needs a reference: give --metrics REF before it, or --heatmap:ref=REF";
        return false;
    }
    HeatmapSettings settings;
    if (!heatmap_settings_of(c, settings, error))
        return false;
    ImageBuf reference, errors, picture;
    mcdn::MetricsOptions options;
    if (!prepare_comparison(s, ref_path, "", reference, options, error))
        return false;
    if (!mcdn::error_map(errors, s.image(), reference, options, settings.kind, {}, s.nthreads)
        || !mcdn::heatmap(picture, errors, settings.log10_min, settings.log10_max, {},
                          s.nthreads)) {
        error = format("{}: {}", c.args[0],
                       errors.has_error() ? errors.geterror() : picture.geterror());
        return false;
    }
    mcdn::WriteOptions wo;
    wo.datatype = OIIO::TypeDesc::UINT8;
    wo.channels = picture.spec().channelnames;
    wo.compression = "";
    return mcdn::write_image(picture, c.args[0], wo, error);
}

bool run_output(Session& s, const Command& c, std::string& error)
{
    if (!s.load(error))
        return false;
    mcdn::WriteOptions options;
    if (!write_options_of(c, options, error) || !s.restore_input_features(error))
        return false;
    options.history = s.history;
    // --ch words with * ? [ are wildcards over the current image's channels, in its order.
    for (const std::string& word : s.output_channels) {
        if (word.find_first_of("*?[") == std::string::npos) {
            options.channels.push_back(word);
            continue;
        }
        size_t before = options.channels.size();
        for (const std::string& name : s.image().spec().channelnames)
            if (fnmatch(word.c_str(), name.c_str(), 0) == 0)
                options.channels.push_back(name);
        if (options.channels.size() == before) {
            error = format("--ch {}: no channel matches (channels: {})", word,
                           mcdn::channel_list(s.image().spec()));
            return false;
        }
    }
    std::vector<std::string> warnings;
    if (!mcdn::write_image(s.image(), c.args[0], options, error, &warnings))
        return false;
    for (const auto& w : warnings)
        std::cerr << "mcdntool: warning: " << w << "\n";
    return true;
}

namespace {

// --fixnan's strategies, oiiotool's names for OIIO's modes.
bool fixnan_mode(const Command& c, OIIO::ImageBufAlgo::NonFiniteFixMode& mode, std::string& error)
{
    using OIIO::ImageBufAlgo::NonFiniteFixMode;
    static const std::pair<const char*, NonFiniteFixMode> modes[] = {
        { "none", NonFiniteFixMode::NONFINITE_NONE },
        { "black", NonFiniteFixMode::NONFINITE_BLACK },
        { "box3", NonFiniteFixMode::NONFINITE_BOX3 },
        { "error", NonFiniteFixMode::NONFINITE_ERROR },
    };
    for (const auto& [name, value] : modes)
        if (c.args[0] == name) {
            mode = value;
            return true;
        }
    error = format("--fixnan {}: needs none, black, box3 or error", c.args[0]);
    return false;
}

}  // namespace

bool check_fixnan(const Command& c, std::string& error)
{
    OIIO::ImageBufAlgo::NonFiniteFixMode mode;
    return fixnan_mode(c, mode, error);
}

bool fix_non_finite(ImageBuf& image, OIIO::ImageBufAlgo::NonFiniteFixMode mode,
                    const std::string& name, int nthreads, int& fixed, std::string& error)
{
    fixed = 0;
    if (OIIO::ImageBufAlgo::fixNonFinite(image, image, mode, &fixed, {}, nthreads))
        return true;
    // OIIO says only that something is not finite: the first such value, by channel.
    std::string where = image.has_error() ? image.geterror() : "non-finite values";
    image.geterror();  // cleared
    const OIIO::ImageSpec& spec = image.spec();
    for (OIIO::ImageBuf::ConstIterator<float> it(image); !it.done(); ++it) {
        int c = 0;
        while (c < spec.nchannels && std::isfinite(it[c]))
            ++c;
        if (c < spec.nchannels) {
            where = format("{}: channel '{}' has {} at pixel ({}, {})",
                           mcdn::channel_source(spec, spec.channelnames[c]), spec.channelnames[c],
                           std::isnan(it[c]) ? "NaN" : "Inf", it.x(), it.y());
            break;
        }
    }
    error = format("--fixnan {}: {}", name, where);
    return false;
}

bool run_fixnan(Session& s, const Command& c, std::string& error)
{
    OIIO::ImageBufAlgo::NonFiniteFixMode fix;
    if (!fixnan_mode(c, fix, error))
        return false;
    const std::string& mode = c.args[0];
    int fixed = 0;
    if (!s.loaded()) {
        // Before the inputs are read: repaired as read, every channel, before they are
        // checked (a NaN in the beauty would stop the frame there), and each neighbour of a
        // cross-frame stage likewise.
        s.input_fix = fix;
        s.input_fix_name = mode;
        if (!s.load(error))
            return false;
        fixed = s.input_fixed;
    } else if (!s.load(error) || !fix_non_finite(s.image(), fix, mode, s.nthreads, fixed, error))
        return false;
    if (s.verbose)
        std::cerr << format("mcdntool: fixnan {}: {} pixels repaired\n", mode, fixed);
    return true;
}

}  // namespace mcdntool
