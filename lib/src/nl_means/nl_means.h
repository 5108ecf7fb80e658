// NL-means with per-pixel variance (Rousselle, Knaus and Zwicker 2012), as NFOR uses it
// (NFOR paper eq. 3-6): the prefilter of the features (§5.1), the regression weights
// (§5.2) and the filtering of the MSE and selection maps (§5.3) all share it.
//
// Distance between pixels p and q of a guide u with variance Var, per channel:
//   d²(p,q) = ((u_p - u_q)² - α (Var_p + min(Var_p, Var_q))) / (ε + k² (Var_p + Var_q))
// (α = 1), clamped to kDistanceClamp, averaged over a (2F+1)² patch with a box filter;
// weight w = exp(-max(0, d²)). The centre pixel's weight is at least kMinCenterWeight so
// that every pixel keeps its own sample.
#pragma once

#include <algorithm>
#include <limits>
#include <vector>

#include "core/planar.h"
#include "core/simd.h"

namespace mcdn {

struct ConvergedTiles;

struct NlMeansParams {
    int patch_radius = 3;         // F: patch (2F+1)²
    int window_radius = 5;        // R: search window (2R+1)²
    float k = 0.5f;               // bandwidth
    float variance_scale = 1.0f;  // variance of the guide = variance plane × this
};

namespace nlm {
constexpr float kEpsilon = 1e-7f;          // keeps d² finite where both variances are 0
constexpr float kDistanceClamp = 1e4f;     // caps outliers before the patch average
constexpr float kMinCenterWeight = 1e-4f;  // the centre pixel always counts
/// Tile side of the NL-means and regression loops (a multiple of the vector width).
constexpr int kTileSize = 32;

/// A rectangle of one plane copied into a padded local buffer, 0 outside the image, so that
/// the tile loops read whole 16-lane vectors without bounds checks.
struct LocalPlane {
    int x0 = 0, y0 = 0;  // image position of element (0, 0)
    int stride = 0;
    std::vector<float> px;
    /// Copies `area` (which may extend past the image) of `src`.
    void load(const float* src, int width, int height, Rect area)
    {
        x0 = area.x0;
        y0 = area.y0;
        stride = area.width();
        px.assign(size_t(stride) * area.height() + kLanes, 0.0f);
        const int cx0 = std::max(area.x0, 0), cx1 = std::min(area.x1, width);
        for (int y = std::max(area.y0, 0); y < std::min(area.y1, height); ++y)
            if (cx0 < cx1)
                std::copy(src + size_t(y) * width + cx0, src + size_t(y) * width + cx1,
                          px.data() + size_t(y - y0) * stride + (cx0 - x0));
    }
    const float* at(int x, int y) const
    {
        return px.data() + ptrdiff_t(y - y0) * stride + (x - x0);
    }
};

MCDN_INLINE int round_up_lanes(int n)
{
    return (n + kLanes - 1) / kLanes * kLanes;
}

/// The area a tile's LocalPlane of the guide (and its variance) must cover for
/// patch_distance with window radius R and patch radius F.
inline Rect guide_area(Rect tile, int R, int F)
{
    const int bws = round_up_lanes(tile.width() + 2 * F);
    return { tile.x0 - F - R, tile.y0 - F - R, tile.x0 - F + R + bws, tile.y1 + F + R };
}

/// The NL-means weight exp(-max(0, d²)) of 16 patch distances; +inf (a neighbour outside the
/// image) gives 0, as exp_neg16 flushes every d >= 80. No explicit `d < inf` test: GCC 12
/// compiles that vector compare against a scalar infinity lane by lane (16 vcomiss), which
/// cost more than the exponential itself. d is never NaN (patch_distance clamps each term).
MCDN_INLINE vfloat16 distance_weight(vfloat16 d)
{
    const vfloat16 zero = {};
    return exp_neg16(d > zero ? d : zero);
}

/// Output rows whose vertical box sums patch_distance computes together (shared loads).
constexpr int kRowBlock = 4;

/// Scratch space for patch_distance on one tile.
struct DistanceScratch {
    std::vector<float> buffer, column_sum, inv_count_x, inv_count;
    int reserved_f = -1;
    void reserve(int tile_size, int patch_radius)
    {
        const int F = patch_radius;
        const size_t bws = size_t(round_up_lanes(tile_size + 2 * F));
        buffer.resize(bws * (tile_size + 2 * F));
        column_sum.resize(kRowBlock * (bws + 2 * F + 2 * kLanes));
        inv_count_x.resize(round_up_lanes(tile_size));
        if (reserved_f != F) {
            inv_count.resize(2 * F + 2);
            inv_count[0] = 0.0f;
            for (int n = 1; n <= 2 * F + 1; ++n)
                inv_count[n] = 1.0f / float(n);
            reserved_f = F;
        }
    }
};

/// Vertical box sum of one output row: out[i] = sum of top[j * bws + i] for j < n, added
/// top to bottom, two vectors side by side (each sum is a chain of dependent adds).
MCDN_INLINE void column_sums_row(float* out, const float* top, int bws, int n)
{
    int i = 0;
    for (; i + 2 * kLanes <= bws; i += 2 * kLanes) {
        vfloat16 s0 = load16(top + i), s1 = load16(top + i + kLanes);
        for (int j = 1; j < n; ++j) {
            s0 += load16(top + size_t(j) * bws + i);
            s1 += load16(top + size_t(j) * bws + i + kLanes);
        }
        store16(out + i, s0);
        store16(out + i + kLanes, s1);
    }
    for (; i < bws; i += kLanes) {
        vfloat16 s0 = load16(top + i);
        for (int j = 1; j < n; ++j)
            s0 += load16(top + size_t(j) * bws + i);
        store16(out + i, s0);
    }
}

/// column_sums_row for kRowBlock consecutive output rows (row r's sum starts at buffer row
/// r, written to out + r * out_stride), N rows each: every buffer row is loaded once for
/// all the sums it enters, and every sum still adds its rows top to bottom (the same
/// result as column_sums_row, with ~3x fewer loads for 7-row sums).
template <int N>
MCDN_INLINE void column_sums_block(float* out, size_t out_stride, const float* top, int bws)
{
    for (int i = 0; i < bws; i += kLanes) {
        vfloat16 s[kRowBlock];
#pragma GCC unroll 16
        for (int j = 0; j < N + kRowBlock - 1; ++j) {
            const vfloat16 v = load16(top + size_t(j) * bws + i);
#pragma GCC unroll 4
            for (int r = 0; r < kRowBlock; ++r) {
                if (j == r)
                    s[r] = v;
                else if (j > r && j < r + N)
                    s[r] += v;
            }
        }
#pragma GCC unroll 4
        for (int r = 0; r < kRowBlock; ++r)
            store16(out + r * out_stride + i, s[r]);
    }
}

/// Patch-averaged distance d²(p, p + (dx, dy)) for every p of `tile`, one channel: the mean
/// over the part of p's patch where both pixels lie inside the image (the box filter of
/// the reference implementation, normalised by the pixel count at the borders).
/// `guide` and `variance` are LocalPlanes covering guide_area(tile, R, F) for |dx|, |dy| <= R.
/// Written to out[(y - tile.y0) * stride + (x - tile.x0)] (rows of round_up_lanes(tile
/// width) writable floats); with `take_max` the result is max(out, d²) (the regression
/// combines colour channels by their largest distance). Pixels whose neighbour falls outside
/// the image get +inf: columns here, rows by the caller, who fills `out` with +inf first.
/// FT: the patch radius when known at compile time (sums unrolled), 0 for any.
/// `guide_q` and `variance_q` hold the neighbours q: another frame aligned to this one (a
/// spatio-temporal window, NFOR §8), or `guide` and `variance` themselves.
template <int FT>
MCDN_INLINE void patch_distance_impl(float* out, int stride, const LocalPlane& guide,
                                     const LocalPlane& variance, const LocalPlane& guide_q,
                                     const LocalPlane& variance_q, int width, int height, Rect tile,
                                     int dx, int dy, int patch_radius, float k,
                                     float variance_scale, bool take_max, DistanceScratch& scratch)
{
    const int F = FT > 0 ? FT : patch_radius;
    const int bx0 = tile.x0 - F, by0 = tile.y0 - F;
    const int bw = tile.width() + 2 * F;
    const int bws = round_up_lanes(bw);
    // Pixels p of the patches with p and p + delta inside the image.
    const int qx0 = std::max(bx0, std::max(0, -dx)),
              qx1 = std::min(tile.x1 + F, std::min(width, width - dx));
    const int qy0 = std::max(by0, std::max(0, -dy)),
              qy1 = std::min(tile.y1 + F, std::min(height, height - dy));
    // Pixels p of the tile whose neighbour p + delta is inside the image.
    const int vx0 = std::max(tile.x0, -dx), vx1 = std::min(tile.x1, width - dx);
    const int vy0 = std::max(tile.y0, -dy), vy1 = std::min(tile.y1, height - dy);
    if (vx0 >= vx1 || vy0 >= vy1)
        return;

    float* buf = scratch.buffer.data();
    const float k2 = k * k;
    const vfloat16 vs = splat16(variance_scale);
    // Buffer rows that touch the valid rows [vy0 - F, vy1 + F); 0 outside [qy0, qy1).
    const int ry0 = vy0 - F, ry1 = vy1 + F;
    for (int y = ry0; y < ry1; ++y) {
        float* b = buf + size_t(y - by0) * bws;
        if (y < qy0 || y >= qy1) {
            std::fill(b, b + bws, 0.0f);
            continue;
        }
        const float* gp = guide.at(bx0, y);
        const float* gq = guide_q.at(bx0 + dx, y + dy);
        const float* vpr = variance.at(bx0, y);
        const float* vqr = variance_q.at(bx0 + dx, y + dy);
        for (int i = 0; i < bws; i += kLanes) {
            vfloat16 vp = load16(vpr + i) * vs, vq = load16(vqr + i) * vs;
            vfloat16 diff = load16(gp + i) - load16(gq + i);
            vfloat16 vmin = vp < vq ? vp : vq;
            vfloat16 num = diff * diff - (vp + vmin);
            vfloat16 d = num / (kEpsilon + k2 * (vp + vq));
            store16(b + i, d < kDistanceClamp ? d : splat16(kDistanceClamp));
        }
        for (int x = bx0; x < qx0; ++x)
            b[x - bx0] = 0.0f;
        for (int x = qx1; x < bx0 + bw; ++x)
            b[x - bx0] = 0.0f;
    }

    // Count of valid patch pixels along x (all 2F+1 away from the image's sides).
    const float* inv_n = scratch.inv_count.data();
    float* inv_cx = scratch.inv_count_x.data();
    const bool x_border = qx0 > vx0 - F || qx1 < vx1 + F;
    const int nxv = round_up_lanes(tile.width());
    if (x_border)
        for (int i = 0; i < nxv; ++i) {
            int x = tile.x0 + i;
            int n = std::min(x + F + 1, qx1) - std::max(x - F, qx0);
            inv_cx[i] = n > 0 ? inv_n[n] : 0.0f;
        }

    const size_t cs_stride = size_t(bws + 2 * F + 2 * kLanes);
    const float inf = std::numeric_limits<float>::infinity();
    for (int y0 = vy0; y0 < vy1; y0 += kRowBlock) {
        // Vertical box sums, summed afresh per row (a running sum would leave rounding residues
        // where the exact sum is 0: identical patches must keep d = 0 exactly, or constant
        // features stop being exactly constant after the prefilter).
        const bool blocked = FT > 0 && y0 + kRowBlock <= vy1;
        if constexpr (FT > 0)
            if (blocked)
                column_sums_block<2 * FT + 1>(scratch.column_sum.data(), cs_stride,
                                              buf + size_t(y0 - F - by0) * bws, bws);
        for (int y = y0; y < std::min(y0 + kRowBlock, vy1); ++y) {
            float* colsum = scratch.column_sum.data() + (blocked ? (y - y0) * cs_stride : 0);
            if (!blocked)
                column_sums_row(colsum, buf + size_t(y - F - by0) * bws, bws, 2 * F + 1);
            const int cy = std::min(y + F + 1, qy1) - std::max(y - F, qy0);
            const float inv_cy = inv_n[cy] * (x_border ? 1.0f : inv_n[2 * F + 1]);
            float* o = out + size_t(y - tile.y0) * stride;
            auto finish = [&](int i, vfloat16 s) {
                vfloat16 d = s * inv_cy;
                if (x_border)
                    d *= load16(inv_cx + i);
                if (take_max) {
                    vfloat16 old = load16(o + i);
                    d = d > old ? d : old;
                }
                store16(o + i, d);
            };
            // colsum index i + j is image column tile.x0 + i + j - F.
            int i = 0;
            for (; i + 2 * kLanes <= nxv; i += 2 * kLanes) {
                vfloat16 s0 = load16(colsum + i), s1 = load16(colsum + i + kLanes);
#pragma GCC unroll 16
                for (int j = 1; j <= 2 * F; ++j) {
                    s0 += load16(colsum + i + j);
                    s1 += load16(colsum + i + kLanes + j);
                }
                finish(i, s0);
                finish(i + kLanes, s1);
            }
            for (; i < nxv; i += kLanes) {
                vfloat16 s0 = load16(colsum + i);
#pragma GCC unroll 16
                for (int j = 1; j <= 2 * F; ++j)
                    s0 += load16(colsum + i + j);
                finish(i, s0);
            }
            // Columns whose neighbour is outside the image, and lanes past the tile, stay +inf
            // (a per-lane mask in the loop above compiles to scalar code).
            for (int x = tile.x0; x < vx0; ++x)
                o[x - tile.x0] = inf;
            for (int x = vx1; x < tile.x0 + nxv; ++x)
                o[x - tile.x0] = inf;
        }
    }
}

/// patch_distance_impl unrolled for the patch radii the defaults use (3: 7×7, 1: 3×3), the
/// neighbours q in `guide_q` and `variance_q`.
MCDN_INLINE void patch_distance_between(float* out, int stride, const LocalPlane& guide,
                                        const LocalPlane& variance, const LocalPlane& guide_q,
                                        const LocalPlane& variance_q, int width, int height,
                                        Rect tile, int dx, int dy, int patch_radius, float k,
                                        float variance_scale, bool take_max,
                                        DistanceScratch& scratch)
{
    if (patch_radius == 3)
        patch_distance_impl<3>(out, stride, guide, variance, guide_q, variance_q, width, height,
                               tile, dx, dy, 3, k, variance_scale, take_max, scratch);
    else if (patch_radius == 1)
        patch_distance_impl<1>(out, stride, guide, variance, guide_q, variance_q, width, height,
                               tile, dx, dy, 1, k, variance_scale, take_max, scratch);
    else
        patch_distance_impl<0>(out, stride, guide, variance, guide_q, variance_q, width, height,
                               tile, dx, dy, patch_radius, k, variance_scale, take_max, scratch);
}

/// The same within one frame.
MCDN_INLINE void patch_distance(float* out, int stride, const LocalPlane& guide,
                                const LocalPlane& variance, int width, int height, Rect tile,
                                int dx, int dy, int patch_radius, float k, float variance_scale,
                                bool take_max, DistanceScratch& scratch)
{
    patch_distance_between(out, stride, guide, variance, guide, variance, width, height, tile, dx,
                           dy, patch_radius, k, variance_scale, take_max, scratch);
}

}  // namespace nlm

/// NL-means filter: channel c of `image` is filtered with the weights of channel
/// c % guide.size() of `guide` and `variance` (per-channel weights, as the reference).
/// All planes have the same size. Deterministic for any thread count. Tiles of `skip`
/// (mcdn/skip.h) are not filtered: the output is the image there.
std::vector<Plane> nl_means(const std::vector<const Plane*>& image,
                            const std::vector<const Plane*>& guide,
                            const std::vector<const Plane*>& variance, const NlMeansParams& params,
                            int nthreads, const ConvergedTiles* skip = nullptr);

}  // namespace mcdn
