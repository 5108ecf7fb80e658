// AOV channel sets: which channels of an image hold the colour, its variance, the half
// buffers and the feature passes that the denoisers read.
//
// Every stage reads one merged ImageBuf. Channels of the main render keep their names;
// channels of the other inputs are prefixed by what they are (see read_inputs in io.h):
//   -i:as=variance  ->  "variance.<name>"     (per-pixel variance of the mean)
//   -i:as=halfA     ->  "A.<name>"            (half buffer A: mean of half the samples)
//   -i:as=halfB     ->  "B.<name>"
// A preset says where each role lives in that merged buffer; `role=ch1,ch2,ch3` overrides
// replace one role at a time.
#pragma once

#include <map>
#include <optional>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

namespace mcdn {

using OIIO::ImageBuf;
using OIIO::ImageSpec;
using OIIO::ROI;
using OIIO::string_view;

/// What a group of channels means to the denoisers.
enum class Role {
    Color,
    ColorVariance,
    ColorA,
    ColorB,
    Albedo,
    AlbedoVariance,
    AlbedoA,
    AlbedoB,
    Normal,
    NormalVariance,
    NormalA,
    NormalB,
    Depth,
    DepthVariance,
    DepthA,
    DepthB,
    Visibility,
    VisibilityVariance,
    VisibilityA,
    VisibilityB,
    // Light components. Either the components themselves (generic preset: `diffuse.*`,
    // `specular.*`) or Blender's factors: diffuse = DiffCol * (DiffDir + DiffInd).
    Diffuse,
    Specular,
    DiffuseColor,
    DiffuseDirect,
    DiffuseIndirect,
    GlossyColor,
    GlossyDirect,
    GlossyIndirect,
    Emission,
    Environment,
    // Motion vectors, 4 channels: towards the previous frame (x, y) and the next (x, y),
    // in pixels, in the preset's convention (Blender's Vector pass, y up; RenderMan's
    // backward.x,y and forward.x,y, y down; ops/motion.h). Read by the cross-frame modes
    // only.
    Motion,
    Count
};

constexpr int kRoleCount = int(Role::Count);

/// The user-facing name of a role: "color", "color_variance", "albedo_a", ...
const char* role_name(Role role);
/// The inverse of role_name; nullopt for an unknown name.
std::optional<Role> role_from_name(string_view name);
/// Number of channels a role holds: 3 for colours and normals, 1 for depth and visibility,
/// 4 for motion.
int role_channel_count(Role role);
/// The four faces of one quantity: the mean, its variance, halves A and B.
enum class Face { Mean, Variance, HalfA, HalfB };
/// The role of one face of a base role (Albedo, Variance) -> AlbedoVariance.
/// Only Color, Albedo, Normal, Depth and Visibility have faces.
Role face_of(Role base, Face face);

/// Which face of the render an input file holds, so where its channels go in the merged
/// buffer (mcdn/io.h read_inputs): a face, by the name -i:as= gives it.
using InputKind = Face;
/// "mean", "variance", "halfA", "halfB" (the -i:as= values).
const char* input_kind_name(InputKind kind);
std::optional<InputKind> input_kind_from_name(string_view name);
/// "", "variance.", "A.", "B.": prefix given to that input's channel names.
const char* input_kind_prefix(InputKind kind);

/// One file given with `-i[:as=KIND] PATH`. For the tungsten preset PATH may be a
/// directory of `color.pfm`, `colorA.pfm`, ... (read_tungsten_directory).
struct InputFile {
    std::string path;
    InputKind kind = InputKind::Mean;
    /// A multi-part EXR's parts to read alone (-i:part=NAME[,NAME...]); empty: every part.
    std::string part;
    /// Renders of this frame that differ only in their seed (-i:as=seed), read as one render
    /// with its variance and halves (mcdn/io.h combine_seeds); `path` is the first of them
    /// and `kind` Mean. Empty: `path` is the one file.
    std::vector<std::string> seeds;

    InputFile() = default;
    InputFile(std::string path_, InputKind kind_ = InputKind::Mean, std::string part_ = {})
        : path(std::move(path_)), kind(kind_), part(std::move(part_))
    { }
};

/// The attribute read_inputs (mcdn/io.h) sets on a merged buffer: one "kind=path" line per
/// file it was read from, in order (ops keep it on their results).
constexpr const char* kInputsAttribute = "mcdn:inputs";
/// The files a merged buffer was read from, from its kInputsAttribute.
std::vector<InputFile> merged_input_files(const ImageSpec& merged);

/// What the user asked for: a preset plus per-role overrides.
struct AovSpec {
    /// cycles | arnold | renderman | tungsten | oidn | generic; empty or "auto": detected
    /// from the channel names (detect_aov_preset).
    std::string preset;
    /// Blender view layer for the cycles preset; empty = the first layer with a Combined pass.
    std::string layer;
    /// OCIO colour space of the colour channels (color.h); empty = the image's
    /// oiio:ColorSpace, else the config's scene_linear role.
    std::string colorspace;
    /// role name -> channel names, replacing the preset's choice for that role.
    std::map<std::string, std::vector<std::string>> overrides;
    /// Extra AOVs to denoise alongside the beauty: name -> channels (light groups, layers).
    std::map<std::string, std::vector<std::string>> extras;

    /// Parses one `role=ch1,ch2,...` (or `extra.NAME=ch1,...`, `layer=NAME`,
    /// `colorspace=NAME`) token.
    bool parse_override(string_view token, std::string& error);
};

/// The names of the presets, in the order --help lists them.
const std::vector<std::string>& aov_presets();

/// A resolved AOV set: for every role present, its channel indices in one merged buffer.
class AovSet {
public:
    bool has(Role role) const { return !m_channels[int(role)].empty(); }
    /// Channel indices of `role` in the buffer it was resolved against (empty if absent).
    const std::vector<int>& channels(Role role) const { return m_channels[int(role)]; }
    /// Channel names of `role`.
    const std::vector<std::string>& names(Role role) const { return m_names[int(role)]; }
    /// First channel index of a role (roles are contiguous or not; use channels() to be sure).
    int first(Role role) const { return has(role) ? m_channels[int(role)][0] : -1; }

    /// An extra AOV and, where the inputs have them, its own variance and half buffers
    /// ("variance.<channel>", "A.<channel>", "B.<channel>"; empty when absent).
    ///
    /// `factor`: the colour pass the extra's light was divided by when rendered (Blender's
    /// DiffDir is diffuse direct light / DiffCol), and `factor_a`/`factor_b` its halves where
    /// the inputs have them; empty when the extra is light itself (a light group, Arnold's
    /// `diffuse`). The working space holds such an extra as light, factor × pass, so that
    /// every op denoises what adds up to the beauty (mcdn/color.h into_working_space).
    struct Extra {
        std::string name;
        std::vector<std::string> names;
        std::vector<int> channels;
        std::vector<int> variance, half_a, half_b;
        std::vector<int> factor, factor_a, factor_b;
        /// The set of extras it belongs to, which may add up to the beauty and whose sum the
        /// denoisers then keep: "light groups", the preset's light passes ("light passes",
        /// Arnold's "direct/indirect" and "by lobe and path", RenderMan's "by path"), or
        /// "extras" (named with extra.NAME=). Sets may overlap each other's light.
        std::string partition;
    };
    const std::vector<Extra>& extras() const { return m_extras; }
    /// The preset the roles were resolved with, and why it was chosen when it was detected
    /// (empty when the spec named it).
    const std::string& preset() const { return m_preset; }
    const std::string& detected_because() const { return m_detected_because; }

    /// True when an extra holds light divided by a factor (Extra::factor).
    bool has_factored_extras() const;

    /// True when the colour is one channel read three times: a luminance-only file (OpenEXR's
    /// Y), denoised as grey; each op writes its three results to that channel, the last
    /// (blue) staying.
    bool grey() const;

    /// True when the light is split into diffuse and specular components (KPCN §4).
    bool has_component_split() const;

    /// Checks that each role in `required` is present. On failure `error` names the role,
    /// the preset, the file the role would come from and the channels that are there.
    bool require(const std::vector<Role>& required, const ImageSpec& merged,
                 std::string& error) const;

private:
    friend bool resolve_aovs(AovSet&, const AovSpec&, const ImageSpec&, std::string&);
    std::string m_preset, m_detected_because;
    std::vector<int> m_channels[kRoleCount];
    std::vector<std::string> m_names[kRoleCount];
    std::vector<Extra> m_extras;
};

/// The feature channels (albedo, normal, depth, visibility: every face) of a resolved set:
/// what a chain with a prefilter puts back into its output from its input unless a stage
/// asked for features-out, and those whose constancy a frame's facts record.
std::vector<std::string> feature_channel_names(const AovSet& aovs, const ImageSpec& spec);

/// Blender's view layers in a merged buffer's channels: each "<layer>" with an un-prefixed
/// "<layer>.Combined.R", in channel order (the cycles preset takes the first unless
/// AovSpec::layer names one).
std::vector<std::string> blender_view_layers(const ImageSpec& merged);

/// The preset whose names a merged buffer's channels follow: cycles (a Blender view layer's
/// "<layer>.Combined.R"), renderman (Ci.r), tungsten (a buffer directory among the inputs),
/// arnold (RGBA.R, a variance layer in the render, RGBA_<group>, denoise_albedo), oidn (a
/// beauty with albedo/normal and no variance or halves), else generic. `why` says which.
std::string detect_aov_preset(const ImageSpec& merged, std::string* why = nullptr);

/// Resolves `spec` against the channel names of a merged buffer. Roles the preset knows but
/// the buffer lacks are simply absent (use AovSet::require); an override or extra naming a
/// channel that is not there is an error.
bool resolve_aovs(AovSet& set, const AovSpec& spec, const ImageSpec& merged, std::string& error);

/// Names the input file a channel of the merged buffer came from, for error messages
/// ("box_var.exr (-i:as=variance)"), from merged_input_files.
std::string channel_source(const ImageSpec& merged, string_view channel);

/// One-line list of a buffer's channel names for error messages, shortened past `max`.
std::string channel_list(const ImageSpec& spec, int max = 16);
/// channel_list of the channels from the same face (render, variance or a half) as
/// `channel`: what the file channel_source names holds (every channel when no such file
/// was given).
std::string source_channel_list(const ImageSpec& merged, string_view channel, int max = 16);

}  // namespace mcdn
