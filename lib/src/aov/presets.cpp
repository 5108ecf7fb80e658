// Where each renderer's preset finds each role (aov/presets.h): the channel names from the
// renderers' own documentation.
#include "aov/presets.h"

namespace mcdn {

std::vector<std::string> with_suffixes(const std::string& stem, const char* suffixes)
{
    std::vector<std::string> names;
    for (const char* s = suffixes; *s; ++s)
        names.push_back(stem + "." + *s);
    return names;
}

// Where a preset keeps the mean face of `role`: channel-name lists to try in order.
// The other faces are the same names behind the input-kind prefix (a separate -i:as= file),
// or where the renderer writes them into the render file itself: preset_face_candidates.
//
// The renderers' names, from their documentation:
// - Cycles (Blender's multilayer EXR, "<layer>.<pass>.<channel>"): Combined, Denoising
//   Albedo/Normal/Depth, DiffCol/Dir/Ind, GlossCol/Dir/Ind, Emit, Env; light groups
//   Combined_<group> (blender intern/cycles/blender/sync.cpp). The compositor's File Output
//   node (multilayer) names channels by its input sockets, by default the passes' names with
//   "Image" for the beauty and no layer: Image.R, Denoising Albedo.R, Denoising Depth.V. No
//   variance pass: K seeds give the mean, the variance of the mean and halves A/B
//   (training/datagen).
// - Arnold (help.autodesk.com, Arnold User Guide: AOVs, Expression AOVs, Arnold Denoiser):
//   the beauty RGBA as R,G,B,A, or RGBA.R,... with "Preserve Layer Name"; N, Z; the albedo
//   LPE AOVs albedo, denoise_albedo, diffuse_albedo; light groups RGBA_<group>. The variance
//   is an output of the beauty through variance_filter, named by the output line; `variance`
//   (variance.R,G,B) is what the noice documentation and the exporters use.
// - RenderMan (rmanwiki.pixar.com, Denoising): Ci (Ci.r,g,b; or R,G,B), a; mse (the error
//   estimate of Ci); albedo, albedo_var; normal, normal_var; zfiltered, zfiltered_var;
//   diffuse, specular (and their _mse); forward and backward, the motion vectors (vector
//   channels x, y, z of motionFore and motionBack: the raster-space displacement of the
//   surface to the next and the previous frame; RenderManForBlender's display-channel
//   definitions).
// - OIDN-style files: the beauty with an albedo and a normal, no variance (what Blender's and
//   OIDN's own denoiser need).
Candidates preset_candidates(const std::string& preset, const std::string& layer, Role role)
{
    if (preset == "cycles") {
        // A view layer's passes "<layer>.<pass>.<channel>"; without a layer, the File Output
        // node's multilayer names: each input socket's name, the beauty's "Image", floats
        // ".V" (Blender's compositor).
        const std::string L = layer.empty() ? "" : layer + ".";
        switch (role) {
        case Role::Color:
            return { with_suffixes(L + "Combined", "RGB"), with_suffixes(L + "Image", "RGB") };
        case Role::Albedo: return { with_suffixes(L + "Denoising Albedo", "RGB") };
        case Role::Normal: return { with_suffixes(L + "Denoising Normal", "XYZ") };
        case Role::Depth:
            return { { L + "Denoising Depth.Z" },
                     { L + "Depth.Z" },
                     { L + "Denoising Depth.V" },
                     { L + "Depth.V" } };
        case Role::DiffuseColor: return { with_suffixes(L + "DiffCol", "RGB") };
        case Role::DiffuseDirect: return { with_suffixes(L + "DiffDir", "RGB") };
        case Role::DiffuseIndirect: return { with_suffixes(L + "DiffInd", "RGB") };
        case Role::GlossyColor: return { with_suffixes(L + "GlossCol", "RGB") };
        case Role::GlossyDirect: return { with_suffixes(L + "GlossDir", "RGB") };
        case Role::GlossyIndirect: return { with_suffixes(L + "GlossInd", "RGB") };
        case Role::Emission: return { with_suffixes(L + "Emit", "RGB") };
        case Role::Environment: return { with_suffixes(L + "Env", "RGB") };
        case Role::Motion: return { with_suffixes(L + "Vector", "XYZW") };
        default: return {};
        }
    }
    if (preset == "arnold") {
        switch (role) {
        case Role::Color: return { { "R", "G", "B" }, with_suffixes("RGBA", "RGB") };
        case Role::Albedo:
            return { with_suffixes("denoise_albedo", "RGB"), with_suffixes("albedo", "RGB"),
                     with_suffixes("diffuse_albedo", "RGB") };
        case Role::Normal: return { with_suffixes("N", "XYZ"), with_suffixes("N", "RGB") };
        case Role::Depth: return { { "Z" }, { "Z.Z" }, { "Z.R" } };
        // Arnold's light-path AOVs (diffuse = diffuse_direct + diffuse_indirect): the CNN's
        // split, the rest of the beauty (specular, transmission, sss, emission) its specular.
        case Role::Diffuse: return { with_suffixes("diffuse", "RGB") };
        case Role::Specular: return { with_suffixes("specular", "RGB") };
        // Not diffuse_albedo as the albedo divided out of the diffuse: on box16 named as
        // Arnold's, --denoise's relMSE went 0.0195 -> 0.0289 with it (the feature albedo is).
        default: return {};
        }
    }
    if (preset == "renderman") {
        switch (role) {
        case Role::Color:
            return { with_suffixes("Ci", "rgb"), with_suffixes("Ci", "RGB"), { "R", "G", "B" } };
        case Role::Albedo:
            return { with_suffixes("albedo", "rgb"), with_suffixes("albedo", "RGB") };
        case Role::Normal:
            return { with_suffixes("normal", "xyz"), with_suffixes("normal", "rgb"),
                     with_suffixes("normal", "XYZ"), with_suffixes("normal", "RGB") };
        case Role::Depth:
            return { { "zfiltered" }, { "zfiltered.r" }, { "zfiltered.z" }, { "zfiltered.Z" } };
        case Role::Diffuse:
            return { with_suffixes("diffuse", "rgb"), with_suffixes("diffuse", "RGB") };
        case Role::Specular:
            return { with_suffixes("specular", "rgb"), with_suffixes("specular", "RGB") };
        case Role::Motion: {
            Candidates c;
            for (const char* xy : { "xy", "XY", "rg", "RG" }) {
                std::vector<std::string> names = with_suffixes("backward", xy);
                for (const std::string& n : with_suffixes("forward", xy))
                    names.push_back(n);
                c.push_back(names);
            }
            return c;
        }
        default: return {};
        }
    }
    // generic, oidn, and tungsten (read_tungsten_directory produces the generic layout)
    switch (role) {
    // A luminance-only file (OpenEXR's Y): its grey as the colour, Y in all three.
    case Role::Color:
        return { { "R", "G", "B" }, with_suffixes("color", "RGB"), { "Y", "Y", "Y" } };
    case Role::Albedo: return { with_suffixes("albedo", "RGB") };
    case Role::Normal:
        return { with_suffixes("N", "XYZ"), with_suffixes("normal", "XYZ"),
                 with_suffixes("normal", "RGB") };
    case Role::Depth: return { { "Z" }, { "depth.Z" }, { "depth" } };
    case Role::Visibility:
        if (preset == "oidn")
            return {};
        return { { "visibility" }, { "visibility.Y" } };
    case Role::Diffuse:
    case Role::Specular:
        if (preset == "oidn")
            return {};
        return { with_suffixes(role == Role::Diffuse ? "diffuse" : "specular", "RGB") };
    default: return {};
    }
}

std::array<float, 4> preset_motion_signs(const std::string& preset)
{
    if (preset == "renderman")
        return { 1.0f, 1.0f, 1.0f, 1.0f };
    return { 1.0f, -1.0f, -1.0f, 1.0f };  // Blender's Vector pass, and what --aov motion= names
}

// Faces a renderer writes into the render file under their own names (tried before the
// prefixed names of a separate -i:as= file).
Candidates preset_face_candidates(const std::string& preset, Role base, Face face)
{
    if (face != Face::Variance)
        return {};
    if (preset == "arnold" && base == Role::Color)
        return { with_suffixes("variance", "RGB"), with_suffixes("RGBA_variance", "RGB"),
                 with_suffixes("beauty_variance", "RGB") };
    if (preset == "renderman") {
        switch (base) {
        case Role::Color: return { with_suffixes("mse", "rgb"), with_suffixes("mse", "RGB") };
        case Role::Albedo:
            return { with_suffixes("albedo_var", "rgb"), with_suffixes("albedo_var", "RGB") };
        case Role::Normal:
            return { with_suffixes("normal_var", "xyz"), with_suffixes("normal_var", "rgb"),
                     with_suffixes("normal_var", "XYZ"), with_suffixes("normal_var", "RGB") };
        case Role::Depth:
            return { { "zfiltered_var" },
                     { "zfiltered_var.r" },
                     { "zfiltered_var.z" },
                     { "zfiltered_var.Z" } };
        default: return {};
        }
    }
    return {};
}

namespace {

// Cycles' light passes and the colour pass each was divided by ("" for none).
constexpr const char* kCyclesLightPasses[][2] = {
    { "DiffDir", "DiffCol" },
    { "DiffInd", "DiffCol" },
    { "GlossDir", "GlossCol" },
    { "GlossInd", "GlossCol" },
    { "TransDir", "TransCol" },
    { "TransInd", "TransCol" },
    { "VolumeDir", "" },
    { "VolumeInd", "" },
    { "Emit", "" },
    { "Env", "" },
};

// Arnold's built-in light-path AOVs (Arnold User Guide: AOVs), each an additive part of the
// beauty in its units, in three sets that each add up to it (with emission and background):
// by lobe, by path, and by both.
struct NamedPass {
    const char* name;
    const char* partition;
};
constexpr NamedPass kArnoldLightPasses[] = {
    { "diffuse", "light passes" },
    { "specular", "light passes" },
    { "coat", "light passes" },
    { "sheen", "light passes" },
    { "transmission", "light passes" },
    { "sss", "light passes" },
    { "volume", "light passes" },
    { "emission", "light passes" },
    { "background", "light passes" },
    { "direct", "direct/indirect" },
    { "indirect", "direct/indirect" },
    { "diffuse_direct", "by lobe and path" },
    { "diffuse_indirect", "by lobe and path" },
    { "specular_direct", "by lobe and path" },
    { "specular_indirect", "by lobe and path" },
    { "coat_direct", "by lobe and path" },
    { "coat_indirect", "by lobe and path" },
    { "sheen_direct", "by lobe and path" },
    { "sheen_indirect", "by lobe and path" },
    { "transmission_direct", "by lobe and path" },
    { "transmission_indirect", "by lobe and path" },
    { "sss_direct", "by lobe and path" },
    { "sss_indirect", "by lobe and path" },
    { "volume_direct", "by lobe and path" },
    { "volume_indirect", "by lobe and path" },
};

// RenderMan's LPE AOVs of its denoising setup (rmanwiki: Denoising, LPE AOVs).
constexpr NamedPass kRendermanLightPasses[] = {
    { "diffuse", "light passes" },     { "specular", "light passes" },
    { "subsurface", "light passes" },  { "transmissive", "light passes" },
    { "emissive", "light passes" },    { "directDiffuse", "by path" },
    { "indirectDiffuse", "by path" },  { "directSpecular", "by path" },
    { "indirectSpecular", "by path" },
};

}  // namespace

std::vector<LightPass> preset_light_passes(const std::string& preset, const std::string& layer)
{
    std::vector<LightPass> passes;
    if (preset == "cycles") {
        const std::string L = layer.empty() ? "" : layer + ".";
        for (const auto& [pass, factor] : kCyclesLightPasses)
            passes.push_back(
                { { with_suffixes(L + pass, "RGB") },
                  *factor ? with_suffixes(L + factor, "RGB") : std::vector<std::string> {},
                  "light passes" });
    } else if (preset == "arnold") {
        for (const NamedPass& pass : kArnoldLightPasses)
            passes.push_back({ { with_suffixes(pass.name, "RGB") }, {}, pass.partition });
    } else if (preset == "renderman") {
        for (const NamedPass& pass : kRendermanLightPasses)
            passes.push_back({ { with_suffixes(pass.name, "rgb"), with_suffixes(pass.name, "RGB") },
                               {},
                               pass.partition });
    }
    return passes;
}

std::vector<std::string> cycles_light_factor(const std::vector<std::string>& names)
{
    for (const auto& [pass, factor] : kCyclesLightPasses) {
        if (!*factor)
            continue;
        std::vector<std::string> out;
        const std::string dotted = std::string(".") + pass + ".";
        for (const std::string& name : names) {
            const std::string padded = "." + name;
            const size_t at = padded.rfind(dotted);
            if (at == std::string::npos)
                break;
            std::string f = padded;
            f.replace(at + 1, std::string(pass).size(), factor);
            out.push_back(f.substr(1));
        }
        if (!out.empty() && out.size() == names.size())
            return out;
    }
    return {};
}

}  // namespace mcdn
