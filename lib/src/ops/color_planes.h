// The colour role's faces as planes, read the same way by every op that needs them.
#pragma once

#include <OpenImageIO/imagebuf.h>

#include "core/frame_facts.h"
#include "core/planar.h"
#include "mcdn/aov.h"

namespace mcdn {

/// The colour role's four faces as planes: mean, variance of the mean, halves A and B.
struct ColorPlanes {
    Plane mean[3], variance[3], half_a[3], half_b[3];
};

/// Reads the colour's faces of src (resolved in `aovs`), the halves when `halves`; without a
/// variance role, the variance of the mean is the halves' squared difference / 4 (the
/// caller has checked that src has one or the other).
void read_color_planes(ColorPlanes& color, const OIIO::ImageBuf& src, const AovSet& aovs,
                       bool halves);

/// The sums core/frame_facts.h takes of the colour (a channel at a time, then added), from
/// the planes read already: sum_abs, sum_sd and n; sum and sum2 stay 0.
ColorSums color_sums(const ColorPlanes& color);

}  // namespace mcdn
