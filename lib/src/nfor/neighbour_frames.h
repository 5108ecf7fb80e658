// The spatio-temporal window of NFOR §8: "We expand our regression window to the
// spatio-temporal domain by including noisy pixels and features from the two previous and
// the two next frames. We include the frame index as an additional auxiliary vector, and
// compute the regression weights using a spatio-temporal NL-Means kernel."
//
// Each neighbouring frame is read as this one is (colour, variance, halves, features), its
// outliers taken out and its features prefiltered (§5.1) in its own pixels, then aligned to
// this frame by the motion vectors (ops/motion.h: the paper did not, its §9 expects them to
// help). Where the alignment leaves the other frame, the guide is set far from any colour,
// so that no patch reaching there gets weight. The first pass (§5.2) fits every window over
// all the frames, the frame offset one more feature; the fits are evaluated on this frame.
// §5.3 and §5.4 stay on this frame, as do extra AOVs (they have no neighbours read).
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "ops/color_planes.h"
#include "core/feature_channels.h"
#include "core/planar.h"
#include "mcdn/aov.h"
#include "outliers/outliers.h"
#include "nfor/regression.h"
#include "prefilter/feature_prefilter.h"

namespace mcdn {

/// One neighbouring frame, aligned to this one.
struct NeighbourFrame {
    int offset = 0;  // frame number relative to this frame
    ColorPlanes color;
    std::vector<FeaturePlanes> features;  // mean and halves (prefiltered), no variance
    Plane offset_feature;                 // `offset` everywhere: the frame index feature
};

/// What reading the neighbours needs of this frame's reading.
struct NeighbourReading {
    const AovSpec* spec = nullptr;  // the user's (its colour space)
    const AovSet* aovs = nullptr;   // resolved on this frame: the neighbours have its channels
    const std::vector<FeatureChannel>* features = nullptr;  // after constant features left out
    bool halves = false;
    bool prefilter = true;  // §5.1 on frames that are not prefiltered yet
    PrefilterOptions prefilter_options;
    bool outliers = true;
    OutlierRule outlier_rule;
};

/// Reads `previous` (frames t-1, t-2, ..., nearest first) and `next` (t+1, t+2, ...) and
/// aligns them to src by the motion vectors of src and of the frames between. Each holds
/// the channels src's roles and features are read from, by name, and src's data window (or
/// src is a band of rows of it: a chain's band, a SURE probe). False with `error` naming
/// the frame and what it lacks.
bool read_neighbour_frames(std::vector<NeighbourFrame>& frames, const ImageBuf& src,
                           const std::vector<const ImageBuf*>& previous,
                           const std::vector<const ImageBuf*>& next,
                           const NeighbourReading& reading, int nthreads, std::string& error);

/// Adds the neighbours to a first-pass regression of this frame: their `image` and `guide`
/// colour faces, their features' `features` face with the offset feature last (the caller
/// adds this frame's: `zero_offset`, a plane of 0). Faces: Mean, HalfA or HalfB.
void add_neighbour_frames(RegressionInputs& in, const std::vector<NeighbourFrame>& frames,
                          Face image, Face guide, Face features, const Plane& zero_offset);

}  // namespace mcdn
