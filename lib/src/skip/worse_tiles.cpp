// The safety net's decision (skip/worse_tiles.h).
#include "skip/worse_tiles.h"

#include <algorithm>
#include <vector>

#include "mcdn/metrics.h"

namespace mcdn {

ConvergedTiles tiles_worse_than_render(const Plane mse[3], const Plane variance[3],
                                       const Plane result[3], const ConvergedTiles& skipped)
{
    const int w = result[0].width, h = result[0].height, t = kConvergedTileSize;
    ConvergedTiles m = empty_tile_map(w, h);
    m.converged.assign(size_t(m.tiles_x) * m.tiles_y, 0);
    std::vector<double> terms;  // the filter's, weighted
    for (int ty = 0; ty < m.tiles_y; ++ty)
        for (int tx = 0; tx < m.tiles_x; ++tx) {
            if (skipped.tile(tx, ty))
                continue;
            terms.clear();
            double render = 0;
            for (int y = ty * t; y < std::min(h, (ty + 1) * t); ++y)
                for (int x = tx * t; x < std::min(w, (tx + 1) * t); ++x)
                    for (int c = 0; c < 3; ++c) {
                        const double r = result[c](x, y);
                        const double weight = 1.0 / (r * r + kRelMseOffset);
                        terms.push_back(double(mse[c](x, y)) * weight);
                        render += double(variance[c](x, y)) * weight;
                    }
            const double filter = top_trimmed_sum(terms);
            m.converged[size_t(ty) * m.tiles_x + tx] = filter > render;
        }
    if (!m.any())
        m.converged.clear();
    return m;
}

double top_trimmed_sum(std::vector<double>& terms)
{
    const size_t n = terms.size(), cut = size_t(double(n) * kFallbackTrim);
    std::nth_element(terms.begin(), terms.begin() + (n - cut), terms.end());
    double sum = 0;
    for (size_t i = 0; i + cut < n; ++i)
        sum += terms[i];
    return sum;
}

}  // namespace mcdn
