#include "core/extra_aovs.h"

#include <OpenImageIO/strutil.h>

#include "core/attributes.h"

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

}  // namespace

bool denoises_extras(bool asked, const ImageBuf& src)
{
    return asked && src.spec().get_int_attribute(kProbeAttribute, 0) == 0;
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
        planes.channels = extra.channels;
        for (int c = 0; c < 3; ++c)
            planes.mean[c] = read_plane(src, extra.channels[c]);
        if (halves) {
            const bool own = !extra.half_a.empty() && !extra.half_b.empty();
            for (int c = 0; c < 3; ++c) {
                if (own) {
                    planes.half_a[c] = read_plane(src, extra.half_a[c]);
                    planes.half_b[c] = read_plane(src, extra.half_b[c]);
                    continue;
                }
                const Plane color = read_plane(src, aovs.channels(Role::Color)[c]);
                planes.half_a[c] = borrowed_half(
                    planes.mean[c], color, read_plane(src, aovs.channels(Role::ColorA)[c]));
                planes.half_b[c] = borrowed_half(
                    planes.mean[c], color, read_plane(src, aovs.channels(Role::ColorB)[c]));
            }
        }
        extras.push_back(std::move(planes));
    }
    return true;
}

}  // namespace mcdn
