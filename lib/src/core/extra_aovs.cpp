#include "core/extra_aovs.h"

#include <OpenImageIO/strutil.h>

#include <algorithm>

#include "core/attributes.h"
#include "core/frame_facts.h"

namespace mcdn {

namespace {

/// The half E_X of an extra without its own halves: E + (C_X − C)·E/C.
Plane borrowed_half(const Plane& extra, const Plane& color, const Plane& color_half)
{
    Plane half = extra;
    for (size_t i = 0; i < half.size(); ++i) {
        const float c = color.px[i];
        if (std::abs(c) > 1e-12f)
            half.px[i] = sanitize(extra.px[i] + (color_half.px[i] - c) * (extra.px[i] / c));
    }
    return half;
}

bool all_zero(const Plane& p)
{
    return std::all_of(p.px.begin(), p.px.end(), [](float v) { return v == 0.0f; });
}

/// An extra that holds 0 over the frame in its mean and its own halves (an empty light
/// group): over the frame's facts in a chain band, over src's planes when src is the frame,
/// and never decided in a band without facts (the decision must not depend on the bands).
bool empty_extra(const AovSet::Extra& extra, const ImageBuf& src, const ExtraPlanes& planes)
{
    const ImageSpec& spec = src.spec();
    std::vector<int> halves = extra.half_a;
    halves.insert(halves.end(), extra.half_b.begin(), extra.half_b.end());
    FrameFacts facts;
    if (frame_facts(facts, spec) && facts.has_constant) {
        auto zero = [&](int ch) {
            auto it = facts.constant.find(spec.channel_name(ch));
            return it != facts.constant.end() && it->second == 0.0f;
        };
        return std::all_of(extra.channels.begin(), extra.channels.end(), zero)
               && std::all_of(halves.begin(), halves.end(), zero);
    }
    if (is_frame_band(spec))
        return false;
    return std::all_of(planes.mean, planes.mean + 3, all_zero)
           && std::all_of(halves.begin(), halves.end(),
                          [&](int ch) { return all_zero(read_plane(src, ch)); });
}

}  // namespace

bool denoises_extras(bool asked, const ImageBuf& src)
{
    return asked && src.spec().get_int_attribute(kProbeAttribute, 0) == 0;
}

bool extra_holds_light(const ImageSpec& spec, const AovSet& aovs,
                       const std::vector<std::string>& names)
{
    if (spec.get_int_attribute(kInWorkingSpaceAttribute) != 1)
        return false;
    return std::any_of(aovs.extras().begin(), aovs.extras().end(), [&](const AovSet::Extra& e) {
        return !e.factor.empty() && e.names == names;
    });
}

bool extras_are_roles(const AovSet& aovs)
{
    for (const AovSet::Extra& e : aovs.extras())
        for (int r = 0; r < kRoleCount; ++r)
            for (int ch : aovs.channels(Role(r)))
                if (std::find(e.channels.begin(), e.channels.end(), ch) != e.channels.end())
                    return true;
    return false;
}

bool read_extras(std::vector<ExtraPlanes>& extras, const ImageBuf& src, const AovSet& aovs,
                 bool halves, std::string& error)
{
    extras.clear();
    for (const AovSet::Extra& extra : aovs.extras()) {
        if (extra.channels.size() != 3) {
            error = OIIO::Strutil::fmt::format(
                "extra aov '{}' has {} channel(s) ({}); the denoisers take RGB extras", extra.name,
                extra.channels.size(), OIIO::Strutil::join(extra.names, ","));
            return false;
        }
        ExtraPlanes planes;
        planes.name = extra.name;
        planes.partition = extra.partition;
        planes.channels = extra.channels;
        for (int c = 0; c < 3; ++c)
            planes.mean[c] = read_plane(src, extra.channels[c]);
        if (empty_extra(extra, src, planes))
            continue;  // nothing to denoise: left as rendered, 0, what any filter gives it
        if (halves) {
            const bool own = !extra.half_a.empty() && !extra.half_b.empty();
            for (int c = 0; c < 3; ++c) {
                if (own) {
                    planes.half_a[c] = read_plane(src, extra.half_a[c]);
                    planes.half_b[c] = read_plane(src, extra.half_b[c]);
                    continue;
                }
                const Plane color = read_plane(src, aovs.channels(Role::Color)[c]);
                planes.half_a[c] = borrowed_half(planes.mean[c], color,
                                                 read_plane(src, aovs.channels(Role::ColorA)[c]));
                planes.half_b[c] = borrowed_half(planes.mean[c], color,
                                                 read_plane(src, aovs.channels(Role::ColorB)[c]));
            }
        }
        extras.push_back(std::move(planes));
    }
    return true;
}

}  // namespace mcdn
