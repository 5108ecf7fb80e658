#include "core/color_planes.h"

namespace mcdn {

void read_color_planes(ColorPlanes& color, const OIIO::ImageBuf& src, const AovSet& aovs,
                       bool halves)
{
    for (int c = 0; c < 3; ++c) {
        color.mean[c] = read_plane(src, aovs.channels(Role::Color)[c]);
        if (halves) {
            color.half_a[c] = read_plane(src, aovs.channels(Role::ColorA)[c]);
            color.half_b[c] = read_plane(src, aovs.channels(Role::ColorB)[c]);
        }
        if (aovs.has(Role::ColorVariance)) {
            color.variance[c] = read_plane(src, aovs.channels(Role::ColorVariance)[c], true);
        } else {  // two-buffer estimate of the variance of the mean
            color.variance[c] = Plane(src.spec().width, src.spec().height);
            for (size_t i = 0; i < color.variance[c].size(); ++i) {
                float d = color.half_a[c].px[i] - color.half_b[c].px[i];
                color.variance[c].px[i] = sanitize_variance(0.25f * d * d);
            }
        }
    }
}

}  // namespace mcdn
