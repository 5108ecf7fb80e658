#include "ops/color_planes.h"

#include <cmath>

namespace mcdn {

void read_color_planes(ColorPlanes& color, const OIIO::ImageBuf& src, const AovSet& aovs,
                       bool halves)
{
    std::vector<PlaneRead> reads;
    for (int c = 0; c < 3; ++c) {
        reads.push_back({ aovs.channels(Role::Color)[c], &color.mean[c] });
        if (halves) {
            reads.push_back({ aovs.channels(Role::ColorA)[c], &color.half_a[c] });
            reads.push_back({ aovs.channels(Role::ColorB)[c], &color.half_b[c] });
        }
        if (aovs.has(Role::ColorVariance))
            reads.push_back({ aovs.channels(Role::ColorVariance)[c], &color.variance[c], true });
    }
    read_planes(src, reads);
    for (int c = 0; c < 3; ++c) {
        if (!aovs.has(Role::ColorVariance)) {  // two-buffer estimate of the variance of the mean
            color.variance[c] = Plane(src.spec().width, src.spec().height);
            for (size_t i = 0; i < color.variance[c].size(); ++i) {
                float d = color.half_a[c].px[i] - color.half_b[c].px[i];
                color.variance[c].px[i] = sanitize_variance(0.25f * d * d);
            }
        }
    }
}

ColorSums color_sums(const ColorPlanes& color)
{
    ColorSums part[3];
    for (int c = 0; c < 3; ++c)
        for (size_t i = 0; i < color.mean[c].size(); ++i, ++part[c].n) {
            part[c].sum_abs += std::fabs(color.mean[c].px[i]);
            part[c].sum_sd += std::sqrt(color.variance[c].px[i]);
        }
    return combined(part);
}

}  // namespace mcdn
