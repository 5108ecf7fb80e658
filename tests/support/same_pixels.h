// Comparing an op's banded result with its whole-frame run (ops/bands.h).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstring>
#include <vector>

#include <OpenImageIO/imagebuf.h>

namespace mcdn_test {

/// Every pixel value of every channel, as floats.
inline std::vector<float> all_pixels(const OIIO::ImageBuf& image)
{
    std::vector<float> values(image.spec().image_pixels() * image.nchannels());
    image.get_pixels(image.roi(), OIIO::TypeDesc::FLOAT, values.data());
    return values;
}

/// Same channels, window and bits (-0 and +0 differ): bit-identical results.
inline bool same_pixels(const OIIO::ImageBuf& a, const OIIO::ImageBuf& b)
{
    if (a.spec().channelnames != b.spec().channelnames || a.roi() != b.roi())
        return false;
    std::vector<float> va = all_pixels(a), vb = all_pixels(b);
    return std::memcmp(va.data(), vb.data(), va.size() * sizeof(float)) == 0;
}

/// Largest absolute difference of any value (images of one shape).
inline float max_difference(const OIIO::ImageBuf& a, const OIIO::ImageBuf& b)
{
    std::vector<float> va = all_pixels(a), vb = all_pixels(b);
    float worst = va.size() == vb.size() ? 0.0f : INFINITY;
    for (size_t i = 0; i < std::min(va.size(), vb.size()); ++i)
        worst = std::max(worst, std::fabs(va[i] - vb[i]));
    return worst;
}

}  // namespace mcdn_test
