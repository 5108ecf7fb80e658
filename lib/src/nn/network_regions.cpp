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
    // Two covers of the non-converged pixels, the cheaper kept: runs of non-converged tiles
    // (unconverged_rects: tight where they are few), and the whole-image run's own tiles, each
    // cut to the bounding box of its non-converged tiles and left out when it has none (never
    // more work than the whole image; fewer, larger windows where a boundary is ragged and
    // runs fragment into many thin rectangles, each with its halo).
    double whole = 0, runs = 0, blocks = 0;
    std::vector<Rect> block_regions;
    const int side = std::max(tile_size / alignment, 1) * alignment;
    const int T = kConvergedTileSize;
    for (int y = 0; y < m.height; y += side)
        for (int x = 0; x < m.width; x += side) {
            const int bx1 = std::min(x + side, m.width), by1 = std::min(y + side, m.height);
            whole += window_area(x, y, bx1, by1);
            int tx0 = m.tiles_x, ty0 = m.tiles_y, tx1 = -1, ty1 = -1;
            for (int ty = y / T; ty <= (by1 - 1) / T; ++ty)
                for (int tx = x / T; tx <= (bx1 - 1) / T; ++tx)
                    if (!m.tile(tx, ty)) {
                        tx0 = std::min(tx0, tx);
                        ty0 = std::min(ty0, ty);
                        tx1 = std::max(tx1, tx);
                        ty1 = std::max(ty1, ty);
                    }
            if (tx1 < 0)
                continue;
            const Rect r { std::max(x, tx0 * T), std::max(y, ty0 * T), std::min(bx1, (tx1 + 1) * T),
                           std::min(by1, (ty1 + 1) * T) };
            block_regions.push_back(r);
            blocks += window_area(r.x0, r.y0, r.x1, r.y1);
        }
    for (const Rect& r : unconverged_rects(m, tile_size, alignment)) {
        regions.push_back({ r.x0, r.y0, r.x1, r.y1 });
        runs += window_area(r.x0, r.y0, r.x1, r.y1);
    }
    if (blocks < runs)
        regions = std::move(block_regions);
    if (std::min(blocks, runs) > kWorthSkipping * whole)
        regions.clear();
    return regions;
}

Rect output_rect(const Rect& core, const OIIO::ImageSpec& spec, OIIO::ROI where)
{
    return { std::max(core.x0, where.xbegin - spec.x), std::max(core.y0, where.ybegin - spec.y),
             std::min(core.x1, where.xend - spec.x), std::min(core.y1, where.yend - spec.y) };
}

bool network_tiles(std::vector<nn::Tile>& tiles, const nn::Net& net,
                   const ConvergedTiles& converged, int tile_size, bool balanced,
                   const OIIO::ImageSpec& spec, OIIO::ROI where, std::string& error)
{
    nn::TileOptions tile_options;
    tile_options.tile_size = tile_size;
    tile_options.balanced = balanced;
    tile_options.regions = network_regions(converged, net, tile_size);
    std::vector<nn::Tile> planned;
    if (!nn::plan_tiles(net, spec.height, spec.width, tile_options, planned, error))
        return false;
    tiles.clear();
    for (const nn::Tile& tile : planned)
        if (!output_rect(tile.core, spec, where).empty())
            tiles.push_back(tile);
    return true;
}

}  // namespace mcdn
