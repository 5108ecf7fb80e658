// AOV channel sets: role names, the presets' channel names, resolution against a merged
// buffer and the error messages that tell a user what is missing.
#include "mcdn/aov.h"

#include "aov/presets.h"

#include <algorithm>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/strutil.h>

namespace mcdn {

using OIIO::Strutil::join;
using OIIO::Strutil::splits;

namespace {

constexpr const char* kRoleNames[kRoleCount] = {
    "color",
    "color_variance",
    "color_a",
    "color_b",
    "albedo",
    "albedo_variance",
    "albedo_a",
    "albedo_b",
    "normal",
    "normal_variance",
    "normal_a",
    "normal_b",
    "depth",
    "depth_variance",
    "depth_a",
    "depth_b",
    "visibility",
    "visibility_variance",
    "visibility_a",
    "visibility_b",
    "diffuse",
    "specular",
    "diffuse_color",
    "diffuse_direct",
    "diffuse_indirect",
    "glossy_color",
    "glossy_direct",
    "glossy_indirect",
    "emission",
    "environment",
    "motion",
};

// Roles that come in four faces (mean, variance, A, B), laid out consecutively in Role.
constexpr Role kFacedRoles[] = { Role::Color, Role::Albedo, Role::Normal, Role::Depth,
                                 Role::Visibility };

// The mean-face role a faced role belongs to, and which face it is.
std::optional<std::pair<Role, Face>> split_face(Role role)
{
    for (Role base : kFacedRoles) {
        int offset = int(role) - int(base);
        if (offset >= 0 && offset < 4)
            return std::make_pair(base, Face(offset));
    }
    return std::nullopt;
}

std::vector<std::string> prefixed(const char* prefix, const std::vector<std::string>& names)
{
    std::vector<std::string> out;
    for (const auto& n : names)
        out.push_back(prefix + n);
    return out;
}

// Indices of all `names` in `spec`, or empty if any is missing.
std::vector<int> find_channels(const ImageSpec& spec, const std::vector<std::string>& names)
{
    std::vector<int> indices;
    for (const auto& n : names) {
        int c = spec.channelindex(n);
        if (c < 0)
            return {};
        indices.push_back(c);
    }
    return indices;
}

bool starts_with_any_prefix(const std::string& name)
{
    for (InputKind k : { InputKind::Variance, InputKind::HalfA, InputKind::HalfB })
        if (OIIO::Strutil::starts_with(name, input_kind_prefix(k)))
            return true;
    return false;
}

// The Blender view layer: the first un-prefixed channel named "<layer>.Combined.R".
std::string find_cycles_layer(const ImageSpec& spec)
{
    const std::string suffix = ".Combined.R";
    for (const auto& name : spec.channelnames)
        if (OIIO::Strutil::ends_with(name, suffix) && !starts_with_any_prefix(name))
            return name.substr(0, name.size() - suffix.size());
    return {};
}

bool has_channel(const ImageSpec& spec, const char* name)
{
    return spec.channelindex(name) >= 0;
}

// Blender's File Output node (multilayer), its default socket names: the beauty as Image
// beside Blender's own pass names, no view layer.
bool file_output_names(const ImageSpec& spec)
{
    return has_channel(spec, "Image.R")
           && (has_channel(spec, "Denoising Albedo.R") || has_channel(spec, "Denoising Normal.X")
               || has_channel(spec, "DiffCol.R") || has_channel(spec, "Denoising Depth.V"));
}

bool has_channel_starting(const ImageSpec& spec, const char* stem)
{
    for (const auto& name : spec.channelnames)
        if (OIIO::Strutil::starts_with(name, stem))
            return true;
    return false;
}

bool has_input_of_kind(const ImageSpec& merged, InputKind kind)
{
    for (const InputFile& file : merged_input_files(merged))
        if (file.kind == kind)
            return true;
    return false;
}

}  // namespace

std::vector<std::string> blender_view_layers(const ImageSpec& spec)
{
    const std::string suffix = ".Combined.R";
    std::vector<std::string> layers;
    for (const auto& name : spec.channelnames)
        if (OIIO::Strutil::ends_with(name, suffix) && !starts_with_any_prefix(name))
            layers.push_back(name.substr(0, name.size() - suffix.size()));
    return layers;
}

std::string detect_aov_preset(const ImageSpec& merged, std::string* why)
{
    auto said = [&](const char* preset, std::string reason) {
        if (why)
            *why = std::move(reason);
        return std::string(preset);
    };
    const std::string layer = find_cycles_layer(merged);
    if (!layer.empty())
        return said("cycles", "Blender view layer '" + layer + "' (" + layer + ".Combined.R)");
    if (file_output_names(merged))
        return said("cycles", "Blender's File Output node names (Image.R beside Blender's "
                              "passes, no view layer)");
    if (has_channel(merged, "Ci.r") || has_channel(merged, "Ci.R"))
        return said("renderman", "RenderMan's Ci channels");
    for (const InputFile& file : merged_input_files(merged))
        if (OIIO::Filesystem::is_directory(file.path))
            return said("tungsten", "a Tungsten buffer directory (" + file.path + ")");
    const bool variance_in_render =
        !has_input_of_kind(merged, InputKind::Variance) && has_channel(merged, "variance.R");
    if (has_channel(merged, "RGBA.R") || variance_in_render
        || has_channel(merged, "denoise_albedo.R") || has_channel(merged, "diffuse_albedo.R")
        || has_channel_starting(merged, "RGBA_"))
        return said("arnold", has_channel(merged, "RGBA.R") ? "Arnold's RGBA layer"
                              : variance_in_render          ? "a variance layer in the render"
                                                            : "Arnold's AOV names");
    const bool features = has_channel(merged, "albedo.R") || has_channel(merged, "N.X")
                          || has_channel(merged, "normal.X") || has_channel(merged, "normal.R");
    const bool variance = has_channel(merged, "variance.R") || has_channel(merged, "A.R");
    if (features && !variance)
        return said("oidn", "a beauty with albedo/normal and no variance or half buffers");
    return said("generic", "no renderer's names (R,G,B, albedo.*, N.*, Z, variance.*)");
}

const char* role_name(Role role)
{
    return kRoleNames[int(role)];
}

std::optional<Role> role_from_name(string_view name)
{
    for (int r = 0; r < kRoleCount; ++r)
        if (name == kRoleNames[r])
            return Role(r);
    return std::nullopt;
}

int role_channel_count(Role role)
{
    if (role == Role::Motion)
        return 4;
    auto faced = split_face(role);
    if (faced && (faced->first == Role::Depth || faced->first == Role::Visibility))
        return 1;
    return 3;
}

Role face_of(Role base, Face face)
{
    return Role(int(base) + int(face));
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

const char* input_kind_name(InputKind kind)
{
    switch (kind) {
    case InputKind::Mean: return "mean";
    case InputKind::Variance: return "variance";
    case InputKind::HalfA: return "halfA";
    case InputKind::HalfB: return "halfB";
    }
    return "?";
}

std::optional<InputKind> input_kind_from_name(string_view name)
{
    for (InputKind k : { InputKind::Mean, InputKind::Variance, InputKind::HalfA, InputKind::HalfB })
        if (name == input_kind_name(k))
            return k;
    return std::nullopt;
}

const char* input_kind_prefix(InputKind kind)
{
    switch (kind) {
    case InputKind::Mean: return "";
    case InputKind::Variance: return "variance.";
    case InputKind::HalfA: return "A.";
    case InputKind::HalfB: return "B.";
    }
    return "";
}

const std::vector<std::string>& aov_presets()
{
    static const std::vector<std::string> presets = { "cycles",   "arnold", "renderman",
                                                      "tungsten", "oidn",   "generic" };
    return presets;
}

bool AovSpec::parse_override(string_view token, std::string& error)
{
    size_t eq = token.find('=');
    if (eq == string_view::npos || eq == 0 || eq + 1 == token.size()) {
        error = OIIO::Strutil::fmt::format(
            "aov override '{}' is not of the form role=channel[,channel...]", token);
        return false;
    }
    std::string key(token.substr(0, eq));
    std::string value(token.substr(eq + 1));
    if (key == "layer") {
        layer = value;
        return true;
    }
    if (key == "preset") {
        preset = value;
        return true;
    }
    if (key == "colorspace") {
        colorspace = value;
        return true;
    }
    std::vector<std::string> channels = splits(value, ",");
    if (key == "extra" || OIIO::Strutil::starts_with(key, "extra.")) {
        // extra.NAME=chans, or extra=chans named after the channels' common layer
        std::string name = key.size() > 6 ? key.substr(6) : channels[0];
        if (key.size() <= 6) {
            size_t dot = name.rfind('.');
            if (dot != std::string::npos)
                name = name.substr(0, dot);
        }
        extras[name] = channels;
        return true;
    }
    auto role = role_from_name(key);
    if (!role) {
        std::vector<std::string> names(std::begin(kRoleNames), std::end(kRoleNames));
        error = OIIO::Strutil::fmt::format(
            "unknown aov role '{}' (roles: {}, extra, extra.NAME, layer, colorspace)", key,
            join(names, ", "));
        return false;
    }
    if (int(channels.size()) != role_channel_count(*role)) {
        error = OIIO::Strutil::fmt::format("aov role '{}' takes {} channel(s), got '{}'", key,
                                           role_channel_count(*role), value);
        return false;
    }
    overrides[key] = channels;
    return true;
}

namespace {

// The AOVs denoised alongside the beauty (AovSet::extras): those the spec names, the light
// groups, the renderer's light passes; each with its faces and, for a Cycles light pass, the
// colour pass it was divided by. `color_variance`: the beauty's variance channels (Arnold's
// RGBA_variance is not a light group).
bool find_extras(std::vector<AovSet::Extra>& extras, const AovSpec& spec, const std::string& preset,
                 const std::string& layer, const ImageSpec& merged,
                 const std::vector<int>& color_variance, std::string& error)
{
    for (const auto& [name, names] : spec.extras) {
        std::vector<int> indices = find_channels(merged, names);
        if (names.empty() || indices.empty()) {
            error = OIIO::Strutil::fmt::format(
                "extra aov '{}' ({}): channel not found in {}; channels there: {}", name,
                join(names, ","), channel_source(merged, names.empty() ? "" : names[0]),
                channel_list(merged));
            return false;
        }
        extras.push_back({ name, names, indices, {}, {}, {}, {}, {}, {}, "extras" });
    }
    // Light groups are denoised alongside: Blender's "<layer>.Combined_<group>.RGB",
    // Arnold's "RGBA_<group>.RGB".
    if ((preset == "cycles" && !layer.empty()) || preset == "arnold") {
        const std::string stem = preset == "cycles" ? layer + ".Combined_" : "RGBA_";
        for (const auto& ch : merged.channelnames) {
            if (OIIO::Strutil::starts_with(ch, stem) && OIIO::Strutil::ends_with(ch, ".R")) {
                std::string group = ch.substr(0, ch.size() - 2);
                std::vector<std::string> names = with_suffixes(group, "RGB");
                std::vector<int> indices = find_channels(merged, names);
                // (Arnold's RGBA_variance is the beauty's variance, not a group.)
                if (!indices.empty() && !spec.extras.count(group) && indices != color_variance)
                    extras.push_back(
                        { group, names, indices, {}, {}, {}, {}, {}, {}, "light groups" });
            }
        }
    }
    // The renderer's light passes too (aov/presets.h), each once; a Cycles pass only with
    // the colour pass its light was divided by (else it is not light: left as rendered).
    for (const LightPass& pass : preset_light_passes(preset, layer)) {
        for (const std::vector<std::string>& names : pass.names) {
            std::vector<int> indices = find_channels(merged, names);
            if (indices.empty())
                continue;
            const bool taken =
                std::any_of(extras.begin(), extras.end(),
                            [&](const AovSet::Extra& e) { return e.channels == indices; });
            if (!taken && (pass.factor.empty() || !find_channels(merged, pass.factor).empty())) {
                AovSet::Extra extra;
                extra.name = names[0].substr(0, names[0].rfind('.'));
                extra.names = names;
                extra.channels = indices;
                extra.partition = pass.partition;
                extras.push_back(extra);
            }
            break;
        }
    }
    const bool cycles = preset == "cycles";
    for (AovSet::Extra& extra : extras) {
        auto face = [&](InputKind kind, const std::vector<std::string>& names) {
            return find_channels(merged, prefixed(input_kind_prefix(kind), names));
        };
        extra.variance = face(InputKind::Variance, extra.names);
        extra.half_a = face(InputKind::HalfA, extra.names);
        extra.half_b = face(InputKind::HalfB, extra.names);
        const std::vector<std::string> factor =
            cycles ? cycles_light_factor(extra.names) : std::vector<std::string> {};
        if (!factor.empty()) {
            extra.factor = find_channels(merged, factor);
            extra.factor_a = face(InputKind::HalfA, factor);
            extra.factor_b = face(InputKind::HalfB, factor);
        }
    }
    return true;
}

}  // namespace

bool resolve_aovs(AovSet& set, const AovSpec& spec, const ImageSpec& merged, std::string& error)
{
    const auto& presets = aov_presets();
    std::string why;
    const std::string preset = spec.preset.empty() || spec.preset == "auto"
                                   ? detect_aov_preset(merged, &why)
                                   : spec.preset;
    if (std::find(presets.begin(), presets.end(), preset) == presets.end()) {
        error = OIIO::Strutil::fmt::format("unknown aov preset '{}' (presets: {}, or auto)", preset,
                                           join(presets, ", "));
        return false;
    }
    set = AovSet();
    set.m_preset = preset;
    set.m_detected_because = why;
    std::string layer = spec.layer;
    if (preset == "cycles" && layer.empty())
        layer = find_cycles_layer(merged);

    // Overrides first: they win, and a misspelt channel is an error rather than "absent".
    std::vector<bool> overridden(kRoleCount, false);
    for (const auto& [role_str, names] : spec.overrides) {
        // AovSpec is a plain struct: overrides written without parse_override are checked too.
        auto parsed = role_from_name(role_str);
        if (!parsed || int(names.size()) != role_channel_count(*parsed)) {
            error = OIIO::Strutil::fmt::format("aov override {}={}: not a role with {} channel(s)",
                                               role_str, join(names, ","),
                                               parsed ? role_channel_count(*parsed) : 0);
            return false;
        }
        Role role = *parsed;
        std::vector<int> indices = find_channels(merged, names);
        if (indices.empty()) {
            error = OIIO::Strutil::fmt::format(
                "aov override {}={}: channel not found in {}; channels there: {}", role_str,
                join(names, ","), channel_source(merged, names[0]),
                source_channel_list(merged, names[0]));
            return false;
        }
        set.m_channels[int(role)] = indices;
        set.m_names[int(role)] = names;
        overridden[int(role)] = true;
    }

    for (int r = 0; r < kRoleCount; ++r) {
        if (overridden[r])
            continue;
        Role role = Role(r);
        auto faced = split_face(role);
        Role base = faced ? faced->first : role;
        const char* prefix = faced ? input_kind_prefix(faced->second) : "";
        Candidates candidates;
        if (faced && faced->second != Face::Mean && overridden[int(base)])
            candidates = { set.m_names[int(base)] };  // faces follow an overridden mean
        else
            candidates = preset_candidates(preset, layer, base);
        for (auto& names : candidates)
            names = prefixed(prefix, names);
        if (faced && !overridden[int(base)]) {  // the renderer's own names first
            Candidates own = preset_face_candidates(preset, base, faced->second);
            candidates.insert(candidates.begin(), own.begin(), own.end());
        }
        for (const auto& full : candidates) {
            std::vector<int> indices = find_channels(merged, full);
            if (!indices.empty()) {
                set.m_channels[r] = indices;
                set.m_names[r] = full;
                break;
            }
        }
    }

    if (!find_extras(set.m_extras, spec, preset, layer, merged,
                     set.m_channels[int(Role::ColorVariance)], error))
        return false;
    return true;
}

bool AovSet::has_factored_extras() const
{
    return std::any_of(m_extras.begin(), m_extras.end(),
                       [](const Extra& e) { return !e.factor.empty(); });
}

bool AovSet::grey() const
{
    const std::vector<int>& c = channels(Role::Color);
    return c.size() == 3 && c[0] == c[1] && c[1] == c[2];
}

bool AovSet::has_component_split() const
{
    if (has(Role::Diffuse) && has(Role::Specular))
        return true;
    for (Role r : { Role::DiffuseColor, Role::DiffuseDirect, Role::DiffuseIndirect,
                    Role::GlossyColor, Role::GlossyDirect, Role::GlossyIndirect })
        if (!has(r))
            return false;
    return true;
}

bool AovSet::require(const std::vector<Role>& required, const ImageSpec& merged,
                     std::string& error) const
{
    for (Role role : required) {
        if (has(role))
            continue;
        auto faced = split_face(role);
        Role base = faced ? faced->first : role;
        const char* prefix = faced ? input_kind_prefix(faced->second) : "";
        std::string layer = m_preset == "cycles" ? find_cycles_layer(merged) : "";
        Candidates candidates =
            faced ? preset_face_candidates(m_preset, base, faced->second) : Candidates();
        for (const auto& names : preset_candidates(m_preset, layer, base))
            candidates.push_back(prefixed(prefix, names));
        std::string wanted = candidates.empty() ? std::string("(no default in this preset)")
                                                : join(candidates[0], ",");
        std::string source = candidates.empty() ? channel_source(merged, prefix)
                                                : channel_source(merged, candidates[0][0]);
        // What to do about it: for the colour's faces that is rendering them (or a stage
        // that does without), not renaming channels.
        std::string fix;
        if (role == Role::ColorA || role == Role::ColorB)
            fix = "render two half buffers (each the mean of half the samples; -i:as=halfA, "
                  "-i:as=halfB), or use a stage that needs none (--denoise, --cnn); if the "
                  "file has them under other names: --aov ";
        else if (role == Role::ColorVariance)
            fix = "give the variance of the mean (the renderer's variance AOV, or "
                  "-i:as=variance FILE), or use a stage that needs none (--cnn; --denoise "
                  "picks it); if the file has it under another name: --aov ";
        else
            fix = "name them with --aov ";
        error = OIIO::Strutil::fmt::format(
            "aov preset '{}': role '{}' not found, looked for {} in {}; channels there: {}; "
            "{}{}=ch1,...",
            m_preset, role_name(role), wanted, source,
            source_channel_list(merged,
                                candidates.empty() ? std::string(prefix) : candidates[0][0]),
            fix, role_name(role));
        return false;
    }
    return true;
}

std::vector<InputFile> merged_input_files(const ImageSpec& merged)
{
    std::vector<InputFile> files;
    const std::string lines = merged.get_string_attribute(kInputsAttribute);
    for (const auto& line : OIIO::Strutil::splits(lines, "\n")) {
        size_t eq = line.find('=');
        auto kind =
            eq == std::string::npos ? std::nullopt : input_kind_from_name(line.substr(0, eq));
        if (kind)
            files.push_back({ line.substr(eq + 1), *kind });
    }
    return files;
}

namespace {

// The face a merged buffer's channel belongs to, by its prefix.
InputKind kind_of_channel(string_view channel)
{
    for (InputKind k : { InputKind::Variance, InputKind::HalfA, InputKind::HalfB })
        if (OIIO::Strutil::starts_with(channel, input_kind_prefix(k)))
            return k;
    return InputKind::Mean;
}

}  // namespace

std::string source_channel_list(const ImageSpec& merged, string_view channel, int max)
{
    const InputKind kind = kind_of_channel(channel);
    ImageSpec same;
    for (const std::string& name : merged.channelnames)
        if (kind_of_channel(name) == kind)
            same.channelnames.push_back(name);
    same.nchannels = int(same.channelnames.size());
    // No such file given: the channels an --aov override could name are all of them.
    return channel_list(same.nchannels ? same : merged, max);
}

std::string channel_source(const ImageSpec& merged, string_view channel)
{
    const InputKind kind = kind_of_channel(channel);
    std::vector<std::string> files;
    for (const InputFile& file : merged_input_files(merged))
        if (file.kind == kind)
            files.push_back(file.path);
    if (files.empty())
        return OIIO::Strutil::fmt::format("the inputs (none given with -i:as={})",
                                          input_kind_name(kind));
    return OIIO::Strutil::fmt::format("{} (-i:as={})", join(files, ", "), input_kind_name(kind));
}

std::string channel_list(const ImageSpec& spec, int max)
{
    std::vector<std::string> names(spec.channelnames.begin(),
                                   spec.channelnames.begin()
                                       + std::min<size_t>(max, spec.channelnames.size()));
    std::string list = join(names, ",");
    if (int(spec.channelnames.size()) > max)
        list += OIIO::Strutil::fmt::format(",... ({} more)", spec.channelnames.size() - max);
    return list;
}

}  // namespace mcdn
