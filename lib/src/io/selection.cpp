// Which faces of the variance and half-buffer files a run reads (mcdn/io.h InputSelection):
// those of the roles its stages read, decided from the files' channel names alone.
#include <algorithm>

#include <OpenImageIO/strutil.h>

#include "aov/transmission.h"
#include "io/io_steps.h"

namespace mcdn {

namespace Strutil = OIIO::Strutil;

namespace {

// The light components only the CNN reads (InputSelection::light_split).
bool is_light_split(Role r)
{
    return r == Role::Diffuse || r == Role::Specular || r == Role::DiffuseColor
           || r == Role::DiffuseDirect || r == Role::DiffuseIndirect || r == Role::GlossyColor
           || r == Role::GlossyDirect || r == Role::GlossyIndirect || r == Role::Emission
           || r == Role::Environment;
}

// A feature's variance or half (InputSelection::all_variances).
bool is_feature_face(Role r)
{
    for (Role base : { Role::Albedo, Role::Normal, Role::Depth, Role::Visibility })
        for (Face face : { Face::Variance, Face::HalfA, Face::HalfB })
            if (r == face_of(base, face))
                return true;
    return false;
}

}  // namespace

std::set<std::string> selected_faces(const ImageSpec& spec, const InputSelection& selection,
                                     std::string& error)
{
    std::set<std::string> wanted;
    // Several view layers: the union of each layer's faces.
    if (!selection.layers.empty()) {
        for (const std::string& layer : selection.layers) {
            InputSelection one = selection;
            one.layers.clear();
            one.aovs.layer = layer;
            const std::set<std::string> faces = selected_faces(spec, one, error);
            if (!error.empty())
                return {};
            wanted.insert(faces.begin(), faces.end());
        }
        return wanted;
    }
    AovSet aovs;
    std::string unresolved;
    if (!resolve_aovs(aovs, selection.aovs, spec, unresolved)) {
        for (const auto& name : spec.channelnames)  // the ops will say what is wrong
            wanted.insert(name);
        return wanted;
    }
    auto add = [&](const std::vector<int>& channels) {
        for (int c : channels)
            wanted.insert(spec.channelnames[c]);
    };
    for (int r = 0; r < kRoleCount; ++r)
        if ((selection.light_split || !is_light_split(Role(r)))
            && (selection.all_variances || !is_feature_face(Role(r))))
            add(aovs.channels(Role(r)));
    for (const AovSet::Extra& e : aovs.extras()) {
        add(e.channels);
        add(e.factor);  // a light pass is denoised as factor × pass (mcdn/color.h)
    }
    // Cycles' transmission passes, which the CNN reads by name (aov/transmission.h): without
    // their faces it would see an incomplete split, and a run would denoise differently from
    // one that reads every channel (a --ch of the variance file's).
    for (const char* pass : kTransmissionPasses)
        for (const std::string& name : transmission_channels(aovs.names(Role::DiffuseColor), pass))
            if (selection.light_split && spec.channelindex(name) >= 0)
                wanted.insert(name);
    // Every face of each of them: roles without faces of their own (Blender's DiffCol,
    // GlossDir, ...) have their variance read by name too (the CNN's delta method); without
    // all_variances, the colour's alone (its variance, or the halves that make it).
    std::vector<std::string> means(selection.extra_features);
    for (const std::string& name : wanted)
        means.push_back(name);
    const std::vector<std::string> color = aovs.names(Role::Color);
    for (const std::string& name : means)
        for (InputKind k : { InputKind::Variance, InputKind::HalfA, InputKind::HalfB })
            if (selection.all_variances
                || std::find(color.begin(), color.end(), name) != color.end())
                wanted.insert(input_kind_prefix(k) + name);
    // Without halves none is read (the half files are not even decoded): that each half file
    // supplies the colour's half is checked here, from the headers, not by validate_inputs.
    if (!selection.halves) {
        if (!check_color_faces(spec, aovs, true, error))
            return {};
        for (auto it = wanted.begin(); it != wanted.end();)
            it = Strutil::starts_with(*it, input_kind_prefix(InputKind::HalfA))
                         || Strutil::starts_with(*it, input_kind_prefix(InputKind::HalfB))
                     ? wanted.erase(it)
                     : std::next(it);
    }
    return wanted;
}

}  // namespace mcdn
