// The two steps of the feature prefilter on planes (§5.1, §5.4), shared by the prefilter
// op and by nfor when its input was not prefiltered.
#pragma once

#include <vector>

#include "core/feature_channels.h"
#include "mcdn/prefilter.h"

namespace mcdn {

struct ConvergedTiles;

/// In place: half_a, half_b <- step 1 (cross-filtered halves); mean <- step 2;
/// variance <- residual variance (A' - B')² / 4 of the filtered halves.
/// Tiles of `skip` (mcdn/skip.h) are not filtered: their halves stay as read, their mean
/// becomes the halves' average and their variance the residual (A - B)² / 4.
void prefilter_planes(std::vector<FeaturePlanes>& features, const PrefilterOptions& options,
                      int nthreads, const ConvergedTiles* skip = nullptr);

}  // namespace mcdn
