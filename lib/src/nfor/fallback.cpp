// The safety net's decision (nfor/fallback.h).
#include "nfor/fallback.h"

#include <algorithm>

namespace mcdn {

ConvergedTiles tiles_worse_than_render(const Plane mse[3], const Plane variance[3],
                                       const Plane result[3], const ConvergedTiles& converged)
{
    const int w = result[0].width, h = result[0].height, t = kConvergedTileSize;
    ConvergedTiles m = empty_tile_map(w, h);
    m.converged.assign(size_t(m.tiles_x) * m.tiles_y, 0);
    for (int ty = 0; ty < m.tiles_y; ++ty)
        for (int tx = 0; tx < m.tiles_x; ++tx) {
            if (converged.tile(tx, ty))
                continue;
            double filter = 0, render = 0;
            for (int y = ty * t; y < std::min(h, (ty + 1) * t); ++y)
                for (int x = tx * t; x < std::min(w, (tx + 1) * t); ++x)
                    for (int c = 0; c < 3; ++c) {
                        const double r = result[c](x, y);
                        const double weight = 1.0 / (r * r + 0.01);
                        filter += weight * mse[c](x, y);
                        render += weight * variance[c](x, y);
                    }
            m.converged[size_t(ty) * m.tiles_x + tx] = filter > render;
        }
    if (!m.any())
        m.converged.clear();
    return m;
}

}  // namespace mcdn
