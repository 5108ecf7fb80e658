// Where a network runs on a frame whose converged tiles are skipped (mcdn/skip.h): the
// rectangles of nn::TileOptions::regions.
#pragma once

#include <vector>

#include "nn/nn.h"
#include "skip/converged_tiles.h"

namespace mcdn {

/// nn::TileOptions::regions for `net`: the unconverged rectangles, or empty (the whole
/// image, as without skipping) when nothing is converged, when their windows (grown by the
/// receptive field) come to more than 90% of the whole image's, or when the net's alignment
/// does not divide the tile size.
std::vector<Rect> network_regions(const ConvergedTiles& tiles, const nn::Net& net, int tile_size);

}  // namespace mcdn
