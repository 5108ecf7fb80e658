// The two steps of the feature prefilter on planes (§5.1, §5.4), shared by the prefilter
// op and by nfor when its input was not prefiltered.
#pragma once

#include <vector>

#include "core/feature_channels.h"
#include "mcdn/prefilter.h"

namespace mcdn {

/// In place: half_a, half_b <- step 1 (cross-filtered halves); mean <- step 2;
/// variance <- residual variance (A' - B')² / 4 of the filtered halves.
void prefilter_planes(std::vector<FeaturePlanes>& features, const PrefilterOptions& options,
                      int nthreads);

}  // namespace mcdn
