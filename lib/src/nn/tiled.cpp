// Tiled inference: a large image is run as tiles, each with a halo of receptive_radius()
// pixels so that every output pixel of the tile's core sees exactly what it would see in a
// whole-image run. Tile windows are clamped to the image (so the image border is the same
// zero padding as in a whole-image run) and start at multiples of alignment() (so the
// pooling grid is the same). Memory is bounded by the tile, not the image; with a TileInputs
// callback (KPCN) not even the inputs exist for the whole image.
#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>

#ifdef _OPENMP
#    include <omp.h>
#endif

#include "nn/nn.h"
#include "nn/ops.h"
#include "nn/parallel.h"

namespace mcdn {
namespace nn {

namespace {

int round_up(int value, int multiple)
{
    return (value + multiple - 1) / multiple * multiple;
}

/// Rows [y0, y1) and columns [x0, x1) of `image` into `window` (its storage reused), where
/// rows and columns past the image's last one repeat it (the extension of a size to a
/// multiple of the alignment).
void extract_window(const Tensor& image, int y0, int y1, int x0, int x1, Tensor& window)
{
    reshape(window, y1 - y0, x1 - x0, image.channels);
    parallel_rows(y1 - y0, [&](int wy) {
        const int y = std::min(y0 + wy, image.height - 1);
        const int inside = std::max(std::min(x1, image.width) - x0, 0);
        std::copy_n(image.pixel(y, x0), size_t(inside) * image.channels, window.pixel(wy, 0));
        for (int x = x0 + inside; x < x1; ++x)
            std::copy_n(image.pixel(y, image.width - 1), image.channels, window.pixel(wy, x - x0));
    });
}

/// Where cores split an extent (a multiple of `alignment`) into n: as evenly as the
/// alignment allows.
std::vector<int> even_edges(int extent, int n, int alignment)
{
    const int units = extent / alignment;
    std::vector<int> edges(size_t(n) + 1);
    for (int i = 0; i <= n; ++i)
        edges[size_t(i)] = int(int64_t(units) * i / n) * alignment;
    return edges;
}

/// Along one axis, for each number of cores n (index n - 1): the windows' total extent and
/// the largest one's.
struct AxisCost {
    std::vector<int64_t> total;
    std::vector<int> largest;
};

AxisCost axis_cost(int extent, int alignment, int halo)
{
    AxisCost cost;
    for (int n = 1; n <= extent / alignment; ++n) {
        const std::vector<int> e = even_edges(extent, n, alignment);
        int64_t total = 0;
        int largest = 0;
        for (int i = 0; i < n; ++i) {
            const int w =
                std::min(e[size_t(i) + 1] + halo, extent) - std::max(e[size_t(i)] - halo, 0);
            total += w;
            largest = std::max(largest, w);
        }
        cost.total.push_back(total);
        cost.largest.push_back(largest);
    }
    return cost;
}

/// TileOptions::balanced: the cores of the grid whose windows add up to the fewest pixels
/// among those whose every window holds at most (tile + 2 × halo)² (fewer tiles on a tie).
std::vector<Rect> balanced_cores(int height, int width, int tile, int halo, int alignment)
{
    const int64_t budget = int64_t(tile + 2 * halo) * (tile + 2 * halo);
    const AxisCost xs = axis_cost(width, alignment, halo), ys = axis_cost(height, alignment, halo);
    size_t best_x = xs.total.size() - 1, best_y = ys.total.size() - 1;
    for (size_t nx = 0; nx < xs.total.size(); ++nx)
        for (size_t ny = 0; ny < ys.total.size(); ++ny) {
            if (int64_t(xs.largest[nx]) * ys.largest[ny] > budget)
                continue;
            const int64_t area = xs.total[nx] * ys.total[ny],
                          best = xs.total[best_x] * ys.total[best_y];
            if (area < best
                || (area == best && (nx + 1) * (ny + 1) < (best_x + 1) * (best_y + 1))) {
                best_x = nx;
                best_y = ny;
            }
            break;  // more rows only add halo
        }
    const std::vector<int> ex = even_edges(width, int(best_x) + 1, alignment),
                           ey = even_edges(height, int(best_y) + 1, alignment);
    std::vector<Rect> cores;
    for (size_t j = 0; j + 1 < ey.size(); ++j)
        for (size_t i = 0; i + 1 < ex.size(); ++i)
            cores.push_back({ ex[i], ey[j], ex[i + 1], ey[j + 1] });
    return cores;
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
    auto cut = [&](const Rect& window, std::vector<Tensor>& tile_inputs, std::string&) {
        tile_inputs.resize(inputs.size());
        for (size_t i = 0; i < inputs.size(); ++i)
            extract_window(inputs[i], window.y0, window.y1, window.x0, window.x1, tile_inputs[i]);
        return true;
    };
    return run_tiled(net, height, width, cut, outputs, error, options);
}

bool plan_tiles(const Net& net, int height, int width, const TileOptions& options,
                std::vector<Tile>& tiles, std::string& error)
{
    const int alignment = net.alignment();
    const int halo = round_up(net.receptive_radius(), alignment);
    const int tile = round_up(std::max(options.tile_size, 1), alignment);
    // The image extended to a multiple of the alignment (last row/column repeated).
    const int padded_height = round_up(height, alignment),
              padded_width = round_up(width, alignment);

    // The output cores: the caller's regions (mcdn/skip.h: only where something is not
    // converged), else a grid of tiles.
    std::vector<Rect> cores = options.regions;
    if (cores.empty() && options.balanced)
        cores = balanced_cores(padded_height, padded_width, tile, halo, alignment);
    if (cores.empty())
        for (int ty = 0; ty < padded_height; ty += tile)
            for (int tx = 0; tx < padded_width; tx += tile)
                cores.push_back({ tx, ty, tx + tile, ty + tile });
    tiles.clear();
    for (const Rect& core : cores) {
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
        tiles.push_back({ { tx, ty, core_x1, core_y1 },
                          { std::max(tx - halo, 0), std::max(ty - halo, 0),
                            std::min(core_x1 + halo, padded_width),
                            std::min(core_y1 + halo, padded_height) } });
    }
    // Largest first: the buffers of the first run then hold every later tile's values
    // (Net::run reuses them), and nothing is allocated after it.
    auto area = [](const Rect& r) { return (r.y1 - r.y0) * (r.x1 - r.x0); };
    std::stable_sort(tiles.begin(), tiles.end(),
                     [&](const Tile& a, const Tile& b) { return area(a.window) > area(b.window); });
    return true;
}

int max_threads()
{
#ifdef _OPENMP
    return omp_get_max_threads();
#else
    return 1;
#endif
}

bool for_each_tile(int count, int workers, const std::function<bool(int, int)>& work)
{
#ifdef _OPENMP
    if (workers > 1 && count > 1) {
        // Nested regions (oneDNN's, parallel_row_blocks) see omp_in_parallel() and run on
        // their worker alone: one tile per core, no barriers between a tile's layers.
        // An exception (out of memory) cannot leave an OpenMP region: the first is kept and
        // thrown again on this thread once the region ends, where the caller can catch it.
        std::atomic<bool> ok { true };
        std::exception_ptr thrown;
        std::mutex first;
#    pragma omp parallel num_threads(workers)
        {
            const int worker = omp_get_thread_num();
#    pragma omp for schedule(dynamic, 1)
            for (int index = 0; index < count; ++index)
                try {
                    if (ok && !work(index, worker))
                        ok = false;
                } catch (...) {
                    std::lock_guard<std::mutex> lock(first);
                    if (!thrown)
                        thrown = std::current_exception();
                    ok = false;
                }
        }
        if (thrown)
            std::rethrow_exception(thrown);
        return ok;
    }
#endif
    for (int index = 0; index < count; ++index)
        if (!work(index, 0))
            return false;
    return true;
}

bool run_tiled(Net& net, int height, int width, const TileInputs& make_inputs,
               std::vector<Tensor>& outputs, std::string& error, const TileOptions& options)
{
    if (height <= 0 || width <= 0) {
        error = "network '" + net.name() + "': run_tiled needs a non-empty image";
        return false;
    }
    std::vector<Tile> tiles;
    if (!plan_tiles(net, height, width, options, tiles, error))
        return false;
    outputs.clear();
    // Kept across tiles: the windows' storage, and the outputs', which run() reuses.
    std::vector<Tensor> tile_inputs, tile_outputs;
    for (const Tile& t : tiles) {
        const Rect& w = t.window;
        if (!make_inputs(w, tile_inputs, error))
            return false;
        if (!net.run(tile_inputs, tile_outputs, error, options.backend))
            return false;
        if (outputs.empty())
            for (const Tensor& out : tile_outputs) {
                if (out.height != w.y1 - w.y0 || out.width != w.x1 - w.x0) {
                    error = "network '" + net.name()
                            + "': run_tiled needs outputs at the input resolution";
                    return false;
                }
                outputs.emplace_back(height, width, out.channels);
            }
        // Keep the tile's core, cropped to the real image.
        const int core_y1 = std::min(t.core.y1, height), core_x1 = std::min(t.core.x1, width);
        for (size_t o = 0; o < outputs.size(); ++o)
            for (int y = t.core.y0; y < core_y1; ++y)
                std::copy_n(tile_outputs[o].pixel(y - w.y0, t.core.x0 - w.x0),
                            size_t(core_x1 - t.core.x0) * outputs[o].channels,
                            outputs[o].pixel(y, t.core.x0));
    }
    return true;
}

}  // namespace nn
}  // namespace mcdn
