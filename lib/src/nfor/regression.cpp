// Collaborative regression over 32×32 tiles. Per tile:
//   1. the NL-means weights w(p, q) of every offset of the window (patch_distance on padded
//      local copies of the guide), stored per tile row: [row][offset][32], so that one
//      row's 361 offsets are contiguous (a [offset][pixel] layout has a 4 KB stride that
//      thrashes the caches);
//   2. for each row of 16 pixels (one vector lane per pixel): the normal equations of the
//      16 windows, accumulated over the window offsets in float, in register-blocked passes
//      (each pass keeps ≤ 24 of the D(D+1)/2 + 3D accumulators in registers and re-reads
//      the design columns it needs); the fits solved in double;
//   3. each fit evaluated over its window and accumulated into the tile's result, which
//      covers the tile grown by R.
// Tiles of one tile row run in parallel; their results are added into the image in tile
// order, so the output does not depend on the thread count.
#include "nfor/regression.h"

#include <limits>

#include <tbb/enumerable_thread_specific.h>

#include "core/nl_means.h"
#include "nfor/least_squares.h"

namespace mcdn {
namespace {

constexpr int T = nlm::kTileSize;
constexpr int L = 16;  // pixels solved together (vector lanes)
static_assert(T % L == 0, "tile side must be a multiple of the lane count");

struct TileScratch {
    nlm::DistanceScratch distance;
    nlm::LocalPlane guide[3], variance[3];
    std::vector<float> dist;      // [T*T] largest channel distance of one offset
    std::vector<float> weights;   // per bandwidth [row][offset][T]
    std::vector<float> local;     // features then colour on the tile grown by R, 0 outside
    std::vector<float> normal;    // accumulators [entry][L]
    std::vector<float> beta;      // [D*3][L]
};

struct TileResult {
    Rect area;                    // tile grown by R, clipped to the image
    int origin_x = 0, origin_y = 0;  // image position of the local buffers' (0, 0)
    int stride = 0;
    std::vector<float> sum;       // per bandwidth: 3 colour planes, the weight plane
};

// The accumulators: the upper triangle of the extended product [x y]^T W [x y] restricted to
// rows i < D (design) and columns j in [i, D + 3) (design, then the 3 colours): X^T W X and
// X^T W Y. Row i starts at row_offset(D, i).
constexpr int row_offset(int D, int i) { return i * (D + 3) - i * (i - 1) / 2; }
constexpr int kMaxLiveAccumulators = 24;
/// End of the register-blocked pass that starts at row i0: as many rows as fit.
constexpr int pass_end(int D, int i0)
{
    int i1 = i0 + 1;
    while (i1 < D && row_offset(D, i1 + 1) - row_offset(D, i0) <= kMaxLiveAccumulators)
        ++i1;
    return i1;
}

struct GroupInputs {
    const float* weights;        // weight of offset o for lane l: weights[o * T + l]
    const float* const* feat;    // local feature planes
    const float* const* color;   // local colour planes
    size_t centre;               // local index of lane 0's pixel
    int stride, R;
    const vfloat16* fp;          // centre features of the 16 pixels
};

/// One pass over the window: rows [I0, I1) of the accumulators, kept in registers.
template<int D, int I0, int I1>
MCDN_INLINE void accumulate_pass(const GroupInputs& g, vfloat16* G)
{
    constexpr int E = D + 3;
    constexpr int N = row_offset(D, I1) - row_offset(D, I0);
    vfloat16 acc[N];
#pragma GCC unroll 64
    for (int e = 0; e < N; ++e)
        acc[e] = vfloat16 {};
    const int R = g.R;
    const float* w_ptr = g.weights;
    for (int dy = -R; dy <= R; ++dy) {
        const size_t qrow = g.centre + ptrdiff_t(dy) * g.stride;
        for (int dx = -R; dx <= R; ++dx, w_ptr += T) {
            const vfloat16 w = load16(w_ptr);
            const size_t q = qrow + dx;
            vfloat16 v[E];
#pragma GCC unroll 32
            for (int j = I0; j < E; ++j) {
                if (j == 0)
                    v[j] = splat16(1.0f);
                else if (j == 1)
                    v[j] = splat16(float(dx));
                else if (j == 2)
                    v[j] = splat16(float(dy));
                else if (j < D)
                    v[j] = load16(g.feat[j - 3] + q) - g.fp[j - 3];
                else
                    v[j] = load16(g.color[j - D] + q);
            }
            int e = 0;
#pragma GCC unroll 32
            for (int i = I0; i < I1; ++i) {
                const vfloat16 wv = i == 0 ? w : w * v[i];
#pragma GCC unroll 32
                for (int j = i; j < E; ++j, ++e)
                    acc[e] += wv * v[j];
            }
        }
    }
#pragma GCC unroll 64
    for (int e = 0; e < N; ++e)
        G[row_offset(D, I0) + e] = acc[e];
}

template<int D, int I0>
MCDN_INLINE void accumulate_normal_equations(const GroupInputs& g, vfloat16* G)
{
    if constexpr (I0 < D) {
        constexpr int I1 = pass_end(D, I0);
        accumulate_pass<D, I0, I1>(g, G);
        accumulate_normal_equations<D, I1>(g, G);
    }
}

template<int D>
MCDN_INLINE void regression_tile_impl(const RegressionInputs& in, Rect tile, TileScratch& s,
                                      TileResult& result)
{
    constexpr int NF = D - 3;
    constexpr int NA = row_offset(D, D);  // accumulators: X^T W X (upper) and X^T W Y
    const int R = in.window_radius, F = in.patch_radius;
    const int width = in.image[0]->width, height = in.image[0]->height;
    const int P = T + 2 * R;  // side of the local buffers (tile grown by R)
    const int noff = (2 * R + 1) * (2 * R + 1);
    const int tw = tile.width(), th = tile.height();
    const float inf = std::numeric_limits<float>::infinity();

    // 1. Weights of every offset for the whole tile, per bandwidth; 0 where p or q is
    // outside the image. The distance is computed once with k = 1: d²(k) = d²(1) / k².
    const int NK = int(in.bandwidths.size());
    const size_t wsize = size_t(noff) * T * T;
    s.distance.reserve(T, F);
    s.dist.resize(size_t(T) * T);
    s.weights.resize(wsize * NK);
    const Rect garea = nlm::guide_area(tile, R, F);
    for (int c = 0; c < 3; ++c) {
        s.guide[c].load(in.guide[c]->data(), width, height, garea);
        s.variance[c].load(in.variance[c]->data(), width, height, garea);
    }
    float inv_k2[16];
    for (int j = 0; j < NK && j < 16; ++j)
        inv_k2[j] = 1.0f / (in.bandwidths[j] * in.bandwidths[j]);
    for (int dy = -R, o = 0; dy <= R; ++dy) {
        for (int dx = -R; dx <= R; ++dx, ++o) {
            float* d = s.dist.data();
            std::fill(d, d + size_t(T) * T, inf);
            for (int c = 0; c < 3; ++c)
                nlm::patch_distance(d, T, s.guide[c], s.variance[c], width, height, tile, dx, dy,
                                    F, 1.0f, in.variance_scale, c > 0, s.distance);
            for (int j = 0; j < NK; ++j) {
                float* wj = s.weights.data() + wsize * j + size_t(o) * T;
                const vfloat16 zero = {}, k = splat16(inv_k2[j]);
                for (int y = 0; y < th; ++y)
                    for (int i = 0; i < T; i += kLanes) {
                        vfloat16 di = load16(d + y * T + i);
                        store16(wj + size_t(y) * noff * T + i,
                                di < inf ? exp_neg16((di > zero ? di : zero) * k) : zero);
                    }
                if (dx == 0 && dy == 0)
                    for (int y = 0; y < th; ++y)
                        for (int x = 0; x < tw; ++x) {
                            float& w = wj[size_t(y) * noff * T + x];
                            w = std::max(w, nlm::kMinCenterWeight);
                        }
            }
        }
    }

    // Local copies of the features and the colour on the tile grown by R (+ one lane row of
    // slack on the right for lanes past the tile edge), 0 outside the image.
    const int PS = P + L;  // row stride of the local buffers
    const size_t plane = size_t(PS) * P;
    s.local.assign(plane * (NF + 3), 0.0f);
    const int ox = tile.x0 - R, oy = tile.y0 - R;
    for (int c = 0; c < NF + 3; ++c) {
        const Plane& src = c < NF ? *in.features[c] : *in.image[c - NF];
        float* dst = s.local.data() + plane * c;
        for (int y = std::max(oy, 0); y < std::min(oy + P, height); ++y) {
            int x0 = std::max(ox, 0), x1 = std::min(ox + P, width);
            std::copy(src.row(y) + x0, src.row(y) + x1, dst + size_t(y - oy) * PS + (x0 - ox));
        }
    }
    const float* feat[NF > 0 ? NF : 1];
    for (int k = 0; k < NF; ++k)
        feat[k] = s.local.data() + plane * k;
    const float* color[3];
    for (int c = 0; c < 3; ++c)
        color[c] = s.local.data() + plane * (NF + c);

    result.area = { std::max(tile.x0 - R, 0), std::max(tile.y0 - R, 0),
                    std::min(tile.x1 + R, width), std::min(tile.y1 + R, height) };
    result.origin_x = ox;
    result.origin_y = oy;
    result.stride = PS;
    result.sum.assign(plane * 4 * NK, 0.0f);

    s.normal.resize(size_t(NA) * L);
    s.beta.resize(size_t(3 * D) * L);
    vfloat16* G = reinterpret_cast<vfloat16*>(s.normal.data());
    vfloat16* B = reinterpret_cast<vfloat16*>(s.beta.data());

    for (int kj = 0; kj < NK; ++kj) {
    float* acc_color[3];
    for (int c = 0; c < 3; ++c)
        acc_color[c] = result.sum.data() + plane * (4 * kj + c);
    float* acc_weight = result.sum.data() + plane * (4 * kj + 3);
    for (int ty = 0; ty < th; ++ty) {
        for (int tx = 0; tx < tw; tx += L) {
            const float* weights = s.weights.data() + wsize * kj + size_t(ty) * noff * T + tx;
            // Centre features of the 16 pixels.
            const size_t centre = size_t(ty + R) * PS + (tx + R);
            vfloat16 fp[NF > 0 ? NF : 1];
            for (int k = 0; k < NF; ++k)
                fp[k] = load16(feat[k] + centre);

            // 2. Normal equations X^T W X and X^T W y, summed over the window (float: the
            // design is centred on the pixel, so the sums do not cancel catastrophically).
            const GroupInputs group { weights, feat, color, centre, PS, R, fp };
            accumulate_normal_equations<D, 0>(group, G);

            // Solve the 16 systems (double).
            const int lanes = std::min(L, tw - tx);
            for (int l = 0; l < L; ++l) {
                if (l >= lanes) {
                    for (int r = 0; r < 3 * D; ++r)
                        B[r][l] = 0.0f;
                    continue;
                }
                double gram[D * D], rhs[D * 3], beta[D * 3];
                for (int i = 0; i < D; ++i) {
                    const int row = row_offset(D, i);
                    for (int j = i; j < D; ++j)
                        gram[i * D + j] = gram[j * D + i] = G[row + j - i][l];
                    for (int c = 0; c < 3; ++c)
                        rhs[i * 3 + c] = G[row + D + c - i][l];
                }
                solve_normal_equations<D>(gram, rhs, beta);
                for (int r = 0; r < 3 * D; ++r) {
                    float b = float(beta[r]);
                    B[r][l] = std::isfinite(b) ? b : 0.0f;
                }
            }

            // 3. Collaborative filtering: evaluate each fit over its window.
            const float* w_ptr = weights;
            for (int dy = -R; dy <= R; ++dy) {
                vfloat16 base[3];
                for (int c = 0; c < 3; ++c)
                    base[c] = B[c] + B[6 + c] * float(dy);
                const size_t qrow = centre + ptrdiff_t(dy) * PS;
                for (int dx = -R; dx <= R; ++dx, w_ptr += T) {
                    const vfloat16 w = load16(w_ptr);
                    const size_t q = qrow + dx;
                    vfloat16 y[3];
                    for (int c = 0; c < 3; ++c)
                        y[c] = base[c] + B[3 + c] * float(dx);
                    for (int k = 0; k < NF; ++k) {
                        vfloat16 xk = load16(feat[k] + q) - fp[k];
                        for (int c = 0; c < 3; ++c)
                            y[c] += B[(3 + k) * 3 + c] * xk;
                    }
                    for (int c = 0; c < 3; ++c)
                        store16(acc_color[c] + q, load16(acc_color[c] + q) + w * y[c]);
                    store16(acc_weight + q, load16(acc_weight + q) + w);
                }
            }
        }
    }
    }
}

using TileKernel = void (*)(const RegressionInputs&, Rect, TileScratch&, TileResult&);

template<int D> void tile_baseline(const RegressionInputs& i, Rect t, TileScratch& s, TileResult& r) { regression_tile_impl<D>(i, t, s, r); }
#if MCDN_X86_DISPATCH
template<int D> MCDN_TARGET_AVX2 void tile_avx2(const RegressionInputs& i, Rect t, TileScratch& s, TileResult& r) { regression_tile_impl<D>(i, t, s, r); }
template<int D> MCDN_TARGET_AVX512 void tile_avx512(const RegressionInputs& i, Rect t, TileScratch& s, TileResult& r) { regression_tile_impl<D>(i, t, s, r); }
#endif

template<int D>
TileKernel kernel_for(Isa isa)
{
#if MCDN_X86_DISPATCH
    if (isa == Isa::Avx512)
        return tile_avx512<D>;
    if (isa == Isa::Avx2)
        return tile_avx2<D>;
#endif
    return tile_baseline<D>;
}

template<int... NFs>
TileKernel select_kernel(int nf, Isa isa, std::integer_sequence<int, NFs...>)
{
    TileKernel k = nullptr;
    ((nf == NFs ? (k = kernel_for<NFs + 3>(isa), 0) : 0), ...);
    return k;
}

}  // namespace

std::vector<std::vector<Plane>> collaborative_regression(const RegressionInputs& in, int nthreads)
{
    const int width = in.image[0]->width, height = in.image[0]->height;
    const int nf = int(in.features.size());
    TileKernel kernel = select_kernel(nf, detect_isa(),
                                      std::make_integer_sequence<int, kMaxRegressionFeatures + 1>());
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
            kernel(in, tiles[row0 + i], scratch.local(), results[i]);
        });
        // Gather in tile order: the sums do not depend on which thread ran which tile.
        for (const TileResult& r : results) {
            const size_t plane = size_t(r.stride) * (T + 2 * in.window_radius);
            for (int j = 0; j < NK; ++j)
                for (int y = r.area.y0; y < r.area.y1; ++y) {
                    const size_t local = size_t(y - r.origin_y) * r.stride - r.origin_x;
                    for (int c = 0; c < 4; ++c) {
                        const float* src = r.sum.data() + plane * (4 * j + c) + local;
                        float* dst = c < 3 ? out[j][c].row(y) : weight_sum[j].row(y);
                        for (int x = r.area.x0; x < r.area.x1; ++x)
                            dst[x] += src[x];
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
