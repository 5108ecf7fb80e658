// Tiled inference: a large image is run as tiles, each with a halo of receptive_radius()
// pixels so that every output pixel of the tile's core sees exactly what it would see in a
// whole-image run. Tile windows are clamped to the image (so the image border is the same
// zero padding as in a whole-image run) and start at multiples of alignment() (so the
// pooling grid is the same). Memory is bounded by the tile, not the image.
#include <algorithm>

#include "mcdn/nn.h"

namespace mcdn {
namespace nn {

namespace {

int round_up(int value, int multiple) { return (value + multiple - 1) / multiple * multiple; }

/// Rows [y0, y1) and columns [x0, x1) of `image`, where rows and columns past the image's
/// last one repeat it (the extension of a size to a multiple of the alignment).
Tensor extract_window(const Tensor& image, int y0, int y1, int x0, int x1)
{
    Tensor window(y1 - y0, x1 - x0, image.channels);
    for (int y = y0; y < y1; ++y)
        for (int x = x0; x < x1; ++x)
            std::copy_n(image.pixel(std::min(y, image.height - 1), std::min(x, image.width - 1)),
                        image.channels, window.pixel(y - y0, x - x0));
    return window;
}

}  // namespace

bool run_tiled(Net& net, const std::vector<Tensor>& inputs, std::vector<Tensor>& outputs,
               std::string& error, const TileOptions& options)
{
    if (inputs.empty() || inputs[0].height <= 0 || inputs[0].width <= 0) {
        error = "network '" + net.name() + "': run_tiled needs non-empty inputs";
        return false;
    }
    const int height = inputs[0].height, width = inputs[0].width;
    for (const Tensor& input : inputs)
        if (input.height != height || input.width != width) {
            error = "network '" + net.name() + "': run_tiled inputs differ in size";
            return false;
        }
    const int alignment = net.alignment();
    const int halo = round_up(net.receptive_radius(), alignment);
    const int tile = round_up(std::max(options.tile_size, 1), alignment);
    // The image extended to a multiple of the alignment (last row/column repeated).
    const int padded_height = round_up(height, alignment), padded_width = round_up(width, alignment);

    std::vector<Region> cores = options.regions;
    if (cores.empty())
        for (int ty = 0; ty < padded_height; ty += tile)
            for (int tx = 0; tx < padded_width; tx += tile)
                cores.push_back({ tx, ty, tx + tile, ty + tile });
    outputs.clear();
    for (const Region& core : cores) {
        const int tx = core.x0, ty = core.y0;
        if (tx % alignment || ty % alignment) {
            error = "network '" + net.name() + "': run_tiled regions must start at multiples of "
                    + std::to_string(alignment);
            return false;
        }
        const int core_y1 = std::min(round_up(core.y1, alignment), padded_height);
        const int core_x1 = std::min(round_up(core.x1, alignment), padded_width);
        if (tx >= core_x1 || ty >= core_y1)
            continue;
        const int y0 = std::max(ty - halo, 0), y1 = std::min(core_y1 + halo, padded_height);
        const int x0 = std::max(tx - halo, 0), x1 = std::min(core_x1 + halo, padded_width);
        std::vector<Tensor> tile_inputs, tile_outputs;
        for (const Tensor& input : inputs)
            tile_inputs.push_back(extract_window(input, y0, y1, x0, x1));
        if (!net.run(tile_inputs, tile_outputs, error, options.backend))
            return false;
        if (outputs.empty())
            for (const Tensor& t : tile_outputs) {
                if (t.height != y1 - y0 || t.width != x1 - x0) {
                    error = "network '" + net.name()
                            + "': run_tiled needs outputs at the input resolution";
                    return false;
                }
                outputs.emplace_back(height, width, t.channels);
            }
        // Keep the tile's core, cropped to the real image.
        for (size_t o = 0; o < outputs.size(); ++o)
            for (int y = ty; y < std::min(core_y1, height); ++y)
                std::copy_n(tile_outputs[o].pixel(y - y0, tx - x0),
                            size_t(std::min(core_x1, width) - tx) * outputs[o].channels,
                            outputs[o].pixel(y, tx));
    }
    return true;
}

}  // namespace nn
}  // namespace mcdn
