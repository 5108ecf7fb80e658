// The tiles the progressive mix leaves to the render (MixOptions::skip, mcdn/skip.h).
#include "mix/mix_steps.h"

namespace mcdn {

ConvergedTiles tiles_mixing_to_x(const ImageBuf& src, const MixInputs& in, const SkipOptions& skip)
{
    ConvergedTiles tiles = converged_tiles_of(src, in.x, in.variance, skip);
    if (!skip.enabled)
        return tiles;
    const int w = in.x[0].width, h = in.x[0].height, T = kConvergedTileSize;
    if (tiles.converged.empty()) {  // none converged: start from an all-zero map
        tiles = ConvergedTiles();
        tiles.width = w;
        tiles.height = h;
        tiles.tiles_x = (w + T - 1) / T;
        tiles.tiles_y = (h + T - 1) / T;
        tiles.converged.assign(size_t(tiles.tiles_x) * tiles.tiles_y, 0);
    }
    // y = x at every pixel of a tile: the denoiser passed it through.
    for (int ty = 0; ty < tiles.tiles_y; ++ty)
        for (int tx = 0; tx < tiles.tiles_x; ++tx) {
            bool same = true;
            for (int c = 0; c < 3 && same; ++c)
                for (int y = ty * T; y < std::min(ty * T + T, h) && same; ++y)
                    for (int x = tx * T; x < std::min(tx * T + T, w) && same; ++x)
                        same = in.x[c](x, y) == in.y[c](x, y);
            if (same)
                tiles.converged[size_t(ty) * tiles.tiles_x + tx] = 1;
        }
    if (!tiles.any())
        tiles.converged.clear();
    return tiles;
}

}  // namespace mcdn
