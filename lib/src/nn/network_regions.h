// Where a network runs on a frame whose converged tiles are skipped (mcdn/skip.h): the
// rectangles of nn::TileOptions::regions.
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "nn/nn.h"
#include "skip/converged_tiles.h"

namespace mcdn {

/// nn::TileOptions::regions for `net`: the unconverged rectangles, or empty (the whole
/// image, as without skipping) when nothing is converged, when their windows (grown by the
/// receptive field) come to more than 90% of the whole image's, or when the net's alignment
/// does not divide the tile size.
std::vector<Rect> network_regions(const ConvergedTiles& tiles, const nn::Net& net, int tile_size);

/// The frame pixels of a tile's core that an op writes: inside the image (`spec`'s data
/// window) and the ROI `where`.
Rect output_rect(const Rect& core, const OIIO::ImageSpec& spec, OIIO::ROI where);

/// The network's tiles (nn/tiled.cpp) on the frame `spec` that write a pixel of `where`, only
/// over tiles that are not converged (network_regions); `balanced`: nn::TileOptions's.
bool network_tiles(std::vector<nn::Tile>& tiles, const nn::Net& net,
                   const ConvergedTiles& converged, int tile_size, bool balanced,
                   const OIIO::ImageSpec& spec, OIIO::ROI where, std::string& error);

}  // namespace mcdn
