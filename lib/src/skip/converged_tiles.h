// The map of converged tiles (mcdn/skip.h says what converged means), decided here once for
// every stage, and the helpers the stages use to skip them: a tile test for the tile loops
// (NL-means, regression), the pass-through of the render, and the rectangles of
// non-converged pixels for the tiled network runs (cnn, mix).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "core/planar.h"
#include "core/extra_aovs.h"
#include "mcdn/aov.h"
#include "mcdn/skip.h"

namespace mcdn {

struct ConvergedTiles {
    int width = 0, height = 0;       // of the image
    int tiles_x = 0, tiles_y = 0;    // tiles of kConvergedTileSize, row-major
    std::vector<uint8_t> converged;  // 1: converged; empty: none is

    bool any() const;
    bool all() const { return any() && count() == int(converged.size()); }
    int count() const;
    bool tile(int tx, int ty) const
    {
        return !converged.empty() && converged[size_t(ty) * tiles_x + tx];
    }
    bool pixel(int x, int y) const { return tile(x / kConvergedTileSize, y / kConvergedTileSize); }
    /// Whether every pixel of `r` (in image coordinates, clipped to the image) is converged.
    bool covers(Rect r) const;
};

/// The tile grid of a width × height image, no tile marked.
ConvergedTiles empty_tile_map(int width, int height);

/// A map of this size attached to src as the string attribute `attribute`
/// (encode_converged_tiles): true and `m` set when there is one.
bool attached_tiles(ConvergedTiles& m, const ImageBuf& src, const char* attribute, int width,
                    int height);

/// Relative standard error of one pixel and channel (mcdn/skip.h).
float relative_standard_error(float mean, float variance_of_mean);

/// The map from the colour and the variance of its mean (sanitized planes, one size).
ConvergedTiles find_converged_tiles(const Plane mean[3], const Plane variance[3],
                                    float max_relative_error);

/// The map an op uses: none when skip is off; the map attached to src by sure
/// (kConvergedAttribute, so that the probes of a denoiser see the same tiles as its first
/// run) when present and of src's size; else find_converged_tiles of src's colour and
/// variance roles (none without a variance role).
ConvergedTiles converged_tiles_of(const ImageBuf& src, const AovSet& aovs, const SkipOptions& skip);
/// The same from planes already read (nfor: its variance may be the two-buffer estimate).
ConvergedTiles converged_tiles_of(const ImageBuf& src, const Plane mean[3], const Plane variance[3],
                                  const SkipOptions& skip);

/// The tiles where a = b at every pixel of the three planes (a denoiser's result that is
/// its input there), restricted to those of `within` when it is given.
ConvergedTiles tiles_where_equal(const Plane a[3], const Plane b[3],
                                 const ConvergedTiles* within = nullptr);

/// String attribute carrying a map from sure to the denoiser it probes: "WxH:0110...".
constexpr const char* kConvergedAttribute = "mcdn:converged_tiles";
std::string encode_converged_tiles(const ConvergedTiles& tiles);
bool decode_converged_tiles(ConvergedTiles& tiles, const std::string& text, int width, int height);

/// out = render on the converged tiles.
void pass_through_converged(Plane& out, const Plane& render, const ConvergedTiles& tiles);
/// A width × height plane, 1 on the map's tiles and 0 elsewhere (an AOV of the tiles).
Plane tile_flags(const ConvergedTiles& tiles, int width, int height);

/// Rectangles covering every non-converged pixel, each at most max_side on a side and
/// starting at a multiple of `alignment` (which must divide kConvergedTileSize): runs of
/// non-converged tiles along a row, merged with the identical runs of the rows below.
std::vector<Rect> unconverged_rects(const ConvergedTiles& tiles, int max_side, int alignment);

/// Writes each extra AOV's render back into its channels of dst on the converged tiles.
void pass_through_extras(ImageBuf& dst, ROI roi, const std::vector<ExtraPlanes>& extras,
                         const ConvergedTiles& tiles);

}  // namespace mcdn
