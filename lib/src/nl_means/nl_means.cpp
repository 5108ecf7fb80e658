// NL-means filter over tiles. Per tile and guide channel: padded local copies of the guide,
// its variance and the images it weights; for each offset of the search window the patch
// distances of the whole tile (patch_distance), their weights, and the weighted sums of the
// shifted images, all in 16-lane vectors over full tile rows (lanes outside the image get
// weight 0).
#include "nl_means/nl_means.h"

#include <tbb/enumerable_thread_specific.h>

#include "skip/converged_tiles.h"

namespace mcdn {
namespace {

struct FilterJob {
    const std::vector<const Plane*>& image;
    const std::vector<const Plane*>& guide;
    const std::vector<const Plane*>& variance;
    const NlMeansParams& params;
    std::vector<Plane>& out;
};

struct FilterScratch {
    nlm::DistanceScratch distance;
    nlm::LocalPlane guide, variance;
    std::vector<nlm::LocalPlane> images;
    std::vector<float> weight, sum, weight_sum;  // tile-sized; sum per image of the guide
};

MCDN_INLINE void filter_tile_impl(const FilterJob& job, Rect tile, FilterScratch& s)
{
    constexpr int T = nlm::kTileSize;
    const int F = job.params.patch_radius, R = job.params.window_radius;
    const int width = job.guide[0]->width, height = job.guide[0]->height;
    const int nimage = int(job.image.size()), nguide = int(job.guide.size());
    const int tw = tile.width(), th = tile.height();
    const float inf = std::numeric_limits<float>::infinity();
    s.distance.reserve(T, F);
    s.weight.resize(size_t(T) * T);
    s.weight_sum.resize(size_t(T) * T);
    const int per_guide = (nimage + nguide - 1) / nguide;
    s.sum.resize(size_t(T) * T * per_guide);
    if (int(s.images.size()) < per_guide)
        s.images.resize(per_guide);
    const Rect garea = nlm::guide_area(tile, R, F);
    // Images read at p + delta for the tile's full 16-lane rows.
    const Rect iarea { tile.x0 - R, tile.y0 - R, tile.x0 + T + R, tile.y1 + R };

    for (int g = 0; g < nguide; ++g) {
        int nimg = 0;
        for (int c = g; c < nimage; c += nguide)
            s.images[nimg++].load(job.image[c]->data(), width, height, iarea);
        if (nimg == 0)
            continue;
        s.guide.load(job.guide[g]->data(), width, height, garea);
        s.variance.load(job.variance[g]->data(), width, height, garea);
        std::fill(s.sum.begin(), s.sum.begin() + size_t(T) * T * nimg, 0.0f);
        std::fill(s.weight_sum.begin(), s.weight_sum.end(), 0.0f);
        for (int dy = -R; dy <= R; ++dy) {
            for (int dx = -R; dx <= R; ++dx) {
                const int vx0 = std::max(tile.x0, -dx), vx1 = std::min(tile.x1, width - dx);
                const int vy0 = std::max(tile.y0, -dy), vy1 = std::min(tile.y1, height - dy);
                if (vx0 >= vx1 || vy0 >= vy1)
                    continue;
                float* w = s.weight.data();
                std::fill(w, w + size_t(T) * T, inf);
                nlm::patch_distance(w, T, s.guide, s.variance, width, height, tile, dx, dy, F,
                                    job.params.k, job.params.variance_scale, false, s.distance);
                for (int i = 0; i < T * T; i += kLanes)
                    store16(w + i, nlm::distance_weight(load16(w + i)));
                if (dx == 0 && dy == 0)
                    for (int y = 0; y < th; ++y)
                        for (int x = 0; x < tw; ++x)
                            w[y * T + x] = std::max(w[y * T + x], nlm::kMinCenterWeight);
                for (int y = 0; y < th; ++y) {
                    const float* wr = w + size_t(y) * T;
                    float* wsr = s.weight_sum.data() + size_t(y) * T;
                    for (int i = 0; i < T; i += kLanes)
                        store16(wsr + i, load16(wsr + i) + load16(wr + i));
                    for (int m = 0; m < nimg; ++m) {
                        const float* src = s.images[m].at(tile.x0 + dx, tile.y0 + y + dy);
                        float* sr = s.sum.data() + size_t(m) * T * T + size_t(y) * T;
                        for (int i = 0; i < T; i += kLanes)
                            store16(sr + i, load16(sr + i) + load16(wr + i) * load16(src + i));
                    }
                }
            }
        }
        int m = 0;
        for (int c = g; c < nimage; c += nguide, ++m)
            for (int y = 0; y < th; ++y) {
                const float* sr = s.sum.data() + size_t(m) * T * T + size_t(y) * T;
                const float* wsr = s.weight_sum.data() + size_t(y) * T;
                float* o = job.out[c].row(tile.y0 + y) + tile.x0;
                for (int x = 0; x < tw; ++x)
                    o[x] = sr[x] / wsr[x];
            }
    }
}

#if MCDN_X86_DISPATCH
MCDN_TARGET_AVX512 void filter_tile_avx512(const FilterJob& j, Rect t, FilterScratch& s)
{
    filter_tile_impl(j, t, s);
}
MCDN_TARGET_AVX2 void filter_tile_avx2(const FilterJob& j, Rect t, FilterScratch& s)
{
    filter_tile_impl(j, t, s);
}
#endif
void filter_tile_baseline(const FilterJob& j, Rect t, FilterScratch& s)
{
    filter_tile_impl(j, t, s);
}

}  // namespace

std::vector<Plane> nl_means(const std::vector<const Plane*>& image,
                            const std::vector<const Plane*>& guide,
                            const std::vector<const Plane*>& variance, const NlMeansParams& params,
                            int nthreads, const ConvergedTiles* skip)
{
    std::vector<Plane> out;
    if (image.empty() || guide.empty())
        return out;
    const int width = guide[0]->width, height = guide[0]->height;
    for (size_t c = 0; c < image.size(); ++c)
        out.emplace_back(width, height);
    FilterJob job { image, guide, variance, params, out };
    auto kernel = filter_tile_baseline;
#if MCDN_X86_DISPATCH
    Isa isa = detect_isa();
    if (isa == Isa::Avx512)
        kernel = filter_tile_avx512;
    else if (isa == Isa::Avx2)
        kernel = filter_tile_avx2;
#endif
    std::vector<Rect> tiles = make_tiles(width, height, nlm::kTileSize);
    // Scratch kept per thread across calls: no page faults for fresh buffers on every call.
    static tbb::enumerable_thread_specific<FilterScratch> scratch;
    parallel_for_index(int(tiles.size()), nthreads, [&](int i) {
        if (!skip || !skip->covers(tiles[i])) {
            const FlushDenormals no_denormals;
            kernel(job, tiles[i], scratch.local());
        }
    });
    if (skip)
        for (size_t c = 0; c < image.size(); ++c)
            pass_through_converged(out[c], *image[c], *skip);
    return out;
}

}  // namespace mcdn
