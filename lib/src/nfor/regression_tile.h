// The tile kernel of the collaborative regression (regression.cpp describes the steps),
// included by the translation units that compile it for one instruction set each:
// regression.cpp (baseline and the run-time design size), regression_avx2.cpp and
// regression_avx512.cpp (fully unrolled for the common design sizes). Splitting them lets a
// parallel build compile the ISA variants side by side.
#pragma once

#include <algorithm>
#include <limits>
#include <type_traits>

#include "nl_means/nl_means.h"
#include "nfor/least_squares.h"
#include "nfor/regression.h"

namespace mcdn {
namespace regression_detail {

constexpr int T = nlm::kTileSize;
constexpr int kMaxDesign = 3 + kMaxRegressionFeatures;
constexpr int L = 16;  // pixels solved together (vector lanes)
constexpr int kMaxBandwidths = 16;
static_assert(T % L == 0, "tile side must be a multiple of the lane count");

struct TileScratch {
    nlm::DistanceScratch distance;
    // Per frame (this one, then RegressionInputs::other_frames): guide and variance, 3 each.
    std::vector<nlm::LocalPlane> guide, variance;
    std::vector<float> dist;     // [T*T] largest channel distance of one offset
    std::vector<float> weights;  // per frame, per stored bandwidth [row][offset][T]
    std::vector<float>
        row_weights;            // per frame a derived bandwidth's weights of one row [offset][T]
    std::vector<float> local;   // per frame features then colour on the tile grown by R, 0 outside
    std::vector<float> normal;  // accumulators [entry][L]
    std::vector<float> beta;    // [D*3][L]
};

struct TileResult {
    Rect area;                       // tile grown by R, clipped to the image
    int origin_x = 0, origin_y = 0;  // image position of the local buffers' (0, 0)
    int stride = 0;
    std::vector<float> sum;  // per bandwidth: 3 colour planes, the weight plane
};

// The accumulators: the upper triangle of the extended product [x y]^T W [x y] restricted to
// rows i < D (design) and columns j in [i, D + 3) (design, then the 3 colours): X^T W X and
// X^T W Y. Row i starts at row_offset(D, i).
constexpr int row_offset(int D, int i)
{
    return i * (D + 3) - i * (i - 1) / 2;
}
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
    const float* weights;       // weight of offset o for lane l: weights[o * T + l]
    const float* const* feat;   // local feature planes
    const float* const* color;  // local colour planes
    size_t centre;              // local index of lane 0's pixel
    int stride, R;
    const vfloat16* fp;  // centre features of the 16 pixels
};

/// One pass over the window: rows [I0, I1) of the accumulators, kept in registers; `add`:
/// added to G (another frame's window), else G is set.
template <int D, int I0, int I1>
MCDN_INLINE void accumulate_pass(const GroupInputs& g, bool add, vfloat16* G)
{
    constexpr int E = D + 3;
    constexpr int N = row_offset(D, I1) - row_offset(D, I0);
    vfloat16 acc[N];
#pragma GCC unroll 64
    for (int e = 0; e < N; ++e)
        acc[e] = add ? G[row_offset(D, I0) + e] : vfloat16 {};
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

template <int D, int I0>
MCDN_INLINE void accumulate_normal_equations(const GroupInputs& g, bool add, vfloat16* G)
{
    if constexpr (I0 < D) {
        constexpr int I1 = pass_end(D, I0);
        accumulate_pass<D, I0, I1>(g, add, G);
        accumulate_normal_equations<D, I1>(g, add, G);
    }
}

/// The same sums for a design size known only at run time: the accumulators stay in memory
/// (L1), slower than the register-blocked passes; for the uncommon sizes.
MCDN_INLINE void accumulate_normal_equations_any(const GroupInputs& g, int D, int NA, bool add,
                                                 vfloat16* G)
{
    const int E = D + 3;
    if (!add)
        for (int e = 0; e < NA; ++e)
            G[e] = vfloat16 {};
    const int R = g.R;
    const float* w_ptr = g.weights;
    vfloat16 v[kMaxDesign + 3];
    v[0] = splat16(1.0f);
    for (int dy = -R; dy <= R; ++dy) {
        const size_t qrow = g.centre + ptrdiff_t(dy) * g.stride;
        v[2] = splat16(float(dy));
        for (int dx = -R; dx <= R; ++dx, w_ptr += T) {
            const vfloat16 w = load16(w_ptr);
            const size_t q = qrow + dx;
            v[1] = splat16(float(dx));
            for (int j = 3; j < D; ++j)
                v[j] = load16(g.feat[j - 3] + q) - g.fp[j - 3];
            for (int j = D; j < E; ++j)
                v[j] = load16(g.color[j - D] + q);
            int e = 0;
            for (int i = 0; i < D; ++i) {
                const vfloat16 wv = i == 0 ? w : w * v[i];
                for (int j = i; j < E; ++j, ++e)
                    G[e] += wv * v[j];
            }
        }
    }
}

/// DT: the design size when known at compile time (unrolled kernels), 0 for any size.
template <int DT>
MCDN_INLINE void regression_tile_impl(const RegressionInputs& in, Rect tile, TileScratch& s,
                                      TileResult& result)
{
    const int D = DT > 0 ? DT : 3 + int(in.features.size());
    const int NF = D - 3;
    const int NA = row_offset(D, D);  // accumulators: X^T W X (upper) and X^T W Y
    constexpr int NFM = DT > 0 ? (DT > 3 ? DT - 3 : 1) : kMaxRegressionFeatures;
    const int R = in.window_radius, F = in.patch_radius;
    const int width = in.image[0]->width, height = in.image[0]->height;
    const int P = T + 2 * R;  // side of the local buffers (tile grown by R)
    const int noff = (2 * R + 1) * (2 * R + 1);
    const int tw = tile.width(), th = tile.height();
    const float inf = std::numeric_limits<float>::infinity();

    // 1. Weights of every offset for the whole tile, per bandwidth; 0 where p or q is
    // outside the image. The distance is computed once with k = 1: d²(k) = d²(1) / k².
    // A bandwidth half another's (the candidates 0.5 and 1) is derived, not stored:
    // exp(-4 d²) = exp(-d²)^4, one row at a time (half the exponentials and the stores).
    const int NK = std::min(int(in.bandwidths.size()), kMaxBandwidths);
    float inv_k2[kMaxBandwidths];
    int source[kMaxBandwidths], slot[kMaxBandwidths], nstored = 0;
    for (int j = 0; j < NK; ++j)
        inv_k2[j] = 1.0f / (in.bandwidths[j] * in.bandwidths[j]);
    for (int j = 0; j < NK; ++j) {
        source[j] = -1;
        for (int i = 0; i < NK; ++i)
            if (source[j] < 0 && i != j && inv_k2[j] == 4.0f * inv_k2[i])
                source[j] = i;
    }
    for (int j = 0; j < NK; ++j) {
        if (source[j] >= 0 && source[source[j]] >= 0)
            source[j] = -1;  // derive from stored weights only
        if (source[j] < 0)
            slot[j] = nstored++;
    }
    // Frames of the window: this one (0), then the other frames; each with its own weights,
    // from this frame's guide at p and that frame's at q.
    const int NFR = 1 + int(in.other_frames.size());
    auto frame_image = [&](int f, int c) {
        return f == 0 ? in.image[c] : in.other_frames[f - 1].image[c];
    };
    auto frame_guide = [&](int f, int c) {
        return f == 0 ? in.guide[c] : in.other_frames[f - 1].guide[c];
    };
    auto frame_variance = [&](int f, int c) {
        return f == 0 ? in.variance[c] : in.other_frames[f - 1].variance[c];
    };
    auto frame_feature = [&](int f, int k) {
        return f == 0 ? in.features[k] : in.other_frames[f - 1].features[k];
    };
    const size_t wsize = size_t(noff) * T * T;
    auto stored_weights = [&](int f, int j) {
        return s.weights.data() + wsize * (size_t(f) * nstored + slot[j]);
    };
    s.distance.reserve(T, F);
    s.dist.resize(size_t(T) * T);
    s.weights.resize(wsize * nstored * NFR);
    s.row_weights.resize(size_t(noff) * T * NFR);
    s.guide.resize(3 * NFR);
    s.variance.resize(3 * NFR);
    const Rect garea = nlm::guide_area(tile, R, F);
    for (int f = 0; f < NFR; ++f)
        for (int c = 0; c < 3; ++c) {
            s.guide[3 * f + c].load(frame_guide(f, c)->data(), width, height, garea);
            s.variance[3 * f + c].load(frame_variance(f, c)->data(), width, height, garea);
        }
    for (int f = 0; f < NFR; ++f) {
        for (int dy = -R, o = 0; dy <= R; ++dy) {
            for (int dx = -R; dx <= R; ++dx, ++o) {
                float* d = s.dist.data();
                std::fill(d, d + size_t(T) * T, inf);
                for (int c = 0; c < 3; ++c)
                    nlm::patch_distance_between(d, T, s.guide[c], s.variance[c], s.guide[3 * f + c],
                                                s.variance[3 * f + c], width, height, tile, dx, dy,
                                                F, 1.0f, in.variance_scale, c > 0, s.distance);
                for (int j = 0; j < NK; ++j) {
                    if (source[j] >= 0)
                        continue;
                    float* wj = stored_weights(f, j) + size_t(o) * T;
                    const vfloat16 k = splat16(inv_k2[j]);
                    for (int y = 0; y < th; ++y)
                        for (int i = 0; i < T; i += kLanes)
                            store16(wj + size_t(y) * noff * T + i,
                                    nlm::distance_weight(load16(d + y * T + i) * k));
                    if (f == 0 && dx == 0 && dy == 0)
                        for (int y = 0; y < th; ++y)
                            for (int x = 0; x < tw; ++x) {
                                float& w = wj[size_t(y) * noff * T + x];
                                w = std::max(w, nlm::kMinCenterWeight);
                            }
                }
            }
        }
    }

    // Local copies of the features and the colour on the tile grown by R (+ one lane row of
    // slack on the right for lanes past the tile edge), 0 outside the image; per frame.
    const int PS = P + L;  // row stride of the local buffers
    const size_t plane = size_t(PS) * P;
    s.local.assign(plane * (NF + 3) * NFR, 0.0f);
    const int ox = tile.x0 - R, oy = tile.y0 - R;
    for (int f = 0; f < NFR; ++f)
        for (int c = 0; c < NF + 3; ++c) {
            const Plane& src = c < NF ? *frame_feature(f, c) : *frame_image(f, c - NF);
            float* dst = s.local.data() + plane * ((NF + 3) * f + c);
            for (int y = std::max(oy, 0); y < std::min(oy + P, height); ++y) {
                int x0 = std::max(ox, 0), x1 = std::min(ox + P, width);
                std::copy(src.row(y) + x0, src.row(y) + x1, dst + size_t(y - oy) * PS + (x0 - ox));
            }
        }
    const float* feat_of[kMaxRegressionFrames][NFM];
    const float* color_of[kMaxRegressionFrames][3];
    for (int f = 0; f < NFR; ++f) {
        for (int k = 0; k < NF; ++k)
            feat_of[f][k] = s.local.data() + plane * ((NF + 3) * f + k);
        for (int c = 0; c < 3; ++c)
            color_of[f][c] = s.local.data() + plane * ((NF + 3) * f + NF + c);
    }
    const float* const* feat = feat_of[0];

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
        const int stored = source[kj] < 0 ? kj : source[kj];
        for (int ty = 0; ty < th; ++ty) {
            const float* row_weights[kMaxRegressionFrames];
            for (int f = 0; f < NFR; ++f) {
                row_weights[f] = stored_weights(f, stored) + size_t(ty) * noff * T;
                if (source[kj] >= 0) {
                    // w^4 = exp(-4 d²); 0 where exp_neg16 would flush exp(-4 d²) (4 d² >= 80), so
                    // no denormals. The centre weight is max(1, kMinCenterWeight)^4 = 1 (d²(p, p)
                    // <= 0).
                    const vfloat16 zero = {}, cutoff = splat16(2.0611536e-9f);  // exp(-20)
                    float* derived = s.row_weights.data() + size_t(f) * noff * T;
                    for (size_t i = 0; i < size_t(noff) * T; i += kLanes) {
                        vfloat16 w = load16(row_weights[f] + i), w2 = w * w;
                        store16(derived + i, w > cutoff ? w2 * w2 : zero);
                    }
                    row_weights[f] = derived;
                }
            }
            for (int tx = 0; tx < tw; tx += L) {
                const float* weights = row_weights[0] + tx;
                // Centre features of the 16 pixels.
                const size_t centre = size_t(ty + R) * PS + (tx + R);
                vfloat16 fp[NFM];
                for (int k = 0; k < NF; ++k)
                    fp[k] = load16(feat[k] + centre);

                // 2. Normal equations X^T W X and X^T W y, summed over the window of every frame
                // (float: the design is centred on the pixel, so the sums do not cancel
                // catastrophically).
                for (int f = 0; f < NFR; ++f) {
                    const GroupInputs group {
                        row_weights[f] + tx, feat_of[f], color_of[f], centre, PS, R, fp
                    };
                    if constexpr (DT > 0)
                        accumulate_normal_equations<DT, 0>(group, f > 0, G);
                    else
                        accumulate_normal_equations_any(group, D, NA, f > 0, G);
                }

                // Solve the 16 systems (double, 8 lanes at a time).
                solve_normal_equations16<DT>(D, G, B, std::min(L, tw - tx));

                // 3. Collaborative filtering: evaluate each fit over its window of this frame.
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

/// The unrolled kernel for `num_features` features, or nullptr where that size is not
/// compiled unrolled (regression_avx2.cpp, regression_avx512.cpp).
TileKernel unrolled_kernel_avx2(int num_features);
TileKernel unrolled_kernel_avx512(int num_features);

/// Number of features with an unrolled kernel: the presets' 7 (albedo, normal, depth) and
/// 8 (+ visibility), and 6 (a feature missing).
template <class F> TileKernel select_unrolled(int nf, F kernel_for)
{
    switch (nf) {
    case 6: return kernel_for(std::integral_constant<int, 9> {});
    case 7: return kernel_for(std::integral_constant<int, 10> {});
    case 8: return kernel_for(std::integral_constant<int, 11> {});
    default: return nullptr;
    }
}

}  // namespace regression_detail
}  // namespace mcdn
