#include "nn/network_regions.h"

#include <algorithm>

namespace mcdn {

namespace {
/// Networks run on the non-converged rectangles only below this fraction of the work.
constexpr double kWorthSkipping = 0.9;
}  // namespace

std::vector<Rect> network_regions(const ConvergedTiles& m, const nn::Net& net, int tile_size)
{
    std::vector<Rect> regions;
    const int alignment = net.alignment();
    if (!m.any() || alignment <= 0 || kConvergedTileSize % alignment != 0)
        return regions;
    // Each run computes its rectangle grown by the halo: worth it when the windows add up
    // to less than the whole image's tiles with theirs. The KPCN op has no whole-frame
    // steps, so its cost follows the windows' area and kWorthSkipping sits near 1.
    const int halo = (net.receptive_radius() + alignment - 1) / alignment * alignment;
    auto window_area = [&](int x0, int y0, int x1, int y1) {
        return double(std::min(x1 + halo, m.width) - std::max(x0 - halo, 0))
               * (std::min(y1 + halo, m.height) - std::max(y0 - halo, 0));
    };
    double whole = 0, skipping = 0;
    const int side = std::max(tile_size / alignment, 1) * alignment;
    for (int y = 0; y < m.height; y += side)
        for (int x = 0; x < m.width; x += side)
            whole += window_area(x, y, x + side, y + side);
    for (const Rect& r : unconverged_rects(m, tile_size, alignment)) {
        regions.push_back({ r.x0, r.y0, r.x1, r.y1 });
        skipping += window_area(r.x0, r.y0, r.x1, r.y1);
    }
    if (skipping > kWorthSkipping * whole)
        regions.clear();
    return regions;
}

}  // namespace mcdn
