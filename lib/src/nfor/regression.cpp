// Collaborative regression over 32×32 tiles. Per tile:
//   1. the NL-means weights w(p, q) of every offset of the window (patch_distance on padded
//      local copies of the guide), stored per tile row: [row][offset][32], so that one
//      row's 361 offsets are contiguous (a [offset][pixel] layout has a 4 KB stride that
//      thrashes the caches);
//   2. for each row of 16 pixels (one vector lane per pixel): the normal equations of the
//      16 windows, accumulated over the window offsets in float, in register-blocked passes
//      (each pass keeps ≤ 24 of the D(D+1)/2 + 3D accumulators in registers and re-reads
//      the design columns it needs); the 16 fits solved together in double (least_squares.h);
//   3. each fit evaluated over its window and accumulated into the tile's result, which
//      covers the tile grown by R.
// Tiles of one tile row run in parallel; their results are added into the image in tile
// order, so the output does not depend on the thread count.
// The tile kernel lives in regression_tile.h: unrolled for the common design sizes in
// regression_avx512.cpp and regression_avx2.cpp, for any size (and the baseline ISA) here.
#include "nfor/regression.h"

#include <tbb/enumerable_thread_specific.h>

#include "skip/converged_tiles.h"
#include "nfor/regression_tile.h"

namespace mcdn {
using namespace regression_detail;
namespace {

void tile_any_baseline(const RegressionInputs& i, Rect t, TileScratch& s, TileResult& r)
{
    regression_tile_impl<0>(i, t, s, r);
}
#if MCDN_X86_DISPATCH
MCDN_TARGET_AVX2 void tile_any_avx2(const RegressionInputs& i, Rect t, TileScratch& s,
                                    TileResult& r)
{
    regression_tile_impl<0>(i, t, s, r);
}
MCDN_TARGET_AVX512 void tile_any_avx512(const RegressionInputs& i, Rect t, TileScratch& s,
                                        TileResult& r)
{
    regression_tile_impl<0>(i, t, s, r);
}
#endif

/// The fastest kernel for `nf` features on this CPU.
TileKernel select_kernel(int nf, Isa isa)
{
#if MCDN_X86_DISPATCH
    if (isa == Isa::Avx512) {
        TileKernel k = unrolled_kernel_avx512(nf);
        return k ? k : tile_any_avx512;
    }
    if (isa == Isa::Avx2) {
        TileKernel k = unrolled_kernel_avx2(nf);
        return k ? k : tile_any_avx2;
    }
#endif
    (void)nf;
    (void)isa;
    return tile_any_baseline;
}

}  // namespace

std::vector<std::vector<Plane>> collaborative_regression(const RegressionInputs& in, int nthreads)
{
    const int width = in.image[0]->width, height = in.image[0]->height;
    const int nf = int(in.features.size());
    bool frames_fit = int(in.other_frames.size()) < kMaxRegressionFrames;
    for (const RegressionFrame& f : in.other_frames)
        frames_fit = frames_fit && f.features.size() == in.features.size();
    TileKernel kernel = nf <= kMaxRegressionFeatures && frames_fit
                            ? select_kernel(in.any_size_kernel ? -1 : nf, detect_isa())
                            : nullptr;
    const int NK = int(in.bandwidths.size());
    std::vector<std::vector<Plane>> out(NK);
    std::vector<Plane> weight_sum(NK);
    for (int j = 0; j < NK; ++j) {
        for (int c = 0; c < 3; ++c)
            out[j].emplace_back(width, height);
        weight_sum[j] = Plane(width, height);
    }
    if (!kernel)
        return out;

    std::vector<Rect> tiles = make_tiles(width, height, T);
    const int tiles_per_row = (width + T - 1) / T;
    // Scratch kept per thread across calls: no page faults for fresh buffers on every call.
    static tbb::enumerable_thread_specific<TileScratch> scratch;
    std::vector<TileResult> results(tiles_per_row);
    for (size_t row0 = 0; row0 < tiles.size(); row0 += tiles_per_row) {
        parallel_for_index(tiles_per_row, nthreads, [&](int i) {
            if (in.skip_tiles && in.skip_tiles->covers(tiles[row0 + i]))
                results[i].area = Rect {};  // gathers nothing
            else {
                const FlushDenormals no_denormals;
                kernel(in, tiles[row0 + i], scratch.local(), results[i]);
            }
        });
        // Gather in tile order: the sums do not depend on which thread ran which tile.
        for (const TileResult& r : results) {
            const size_t plane = size_t(r.stride) * (T + 2 * in.window_radius);
            for (int j = 0; j < NK; ++j)
                for (int y = r.area.y0; y < r.area.y1; ++y) {
                    // Index from the tile row's start: a pointer moved back by origin_x
                    // first would wrap around (UB).
                    const size_t row = size_t(y - r.origin_y) * r.stride;
                    for (int c = 0; c < 4; ++c) {
                        const float* src = r.sum.data() + plane * (4 * j + c) + row;
                        float* dst = c < 3 ? out[j][c].row(y) : weight_sum[j].row(y);
                        for (int x = r.area.x0; x < r.area.x1; ++x)
                            dst[x] += src[x - r.origin_x];
                    }
                }
        }
    }
    // Every pixel is covered by its own fit with weight >= kMinCenterWeight.
    for (int j = 0; j < NK; ++j)
        for (int c = 0; c < 3; ++c)
            for (size_t i = 0; i < out[j][c].size(); ++i) {
                float v = out[j][c].px[i] / weight_sum[j].px[i];
                out[j][c].px[i] = std::isfinite(v) ? v : in.image[c]->px[i];
            }
    if (in.skip_tiles)
        for (int j = 0; j < NK; ++j)
            for (int c = 0; c < 3; ++c)
                pass_through_converged(out[j][c], *in.image[c], *in.skip_tiles);
    return out;
}

}  // namespace mcdn

namespace mcdn {
double regression_flops_per_pixel(int nf, int R, int F)
{
    const double d = 3 + nf, n = (2 * R + 1) * (2 * R + 1);
    // weights: 3 channels × (distance 9 + box sums 2(2F+1)) + max/exp ~20, per offset (the
    // padding of the patch buffer adds ~(T+2F)²/T²);
    double weights = n * (3 * (9.0 * (T + 2 * F) * (T + 2 * F) / (T * T) + 2 * (2 * F + 1)) + 20);
    double normal = n * (nf + d + 2 * (d * (d + 1) / 2 + 3 * d));  // x, w·x, FMAs
    double solve = d * d * d / 3 + 6 * d * d;
    double apply = n * (nf + 2 * 3 * d + 8);
    return weights + normal + solve + apply;
}
}  // namespace mcdn
