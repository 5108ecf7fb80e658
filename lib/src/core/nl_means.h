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

struct NlMeansParams {
    int patch_radius = 3;        // F: patch (2F+1)²
    int window_radius = 5;       // R: search window (2R+1)²
    float k = 0.5f;              // bandwidth
    float variance_scale = 1.0f; // variance of the guide = variance plane × this
};

namespace nlm {
constexpr float kEpsilon = 1e-7f;          // keeps d² finite where both variances are 0
constexpr float kDistanceClamp = 1e4f;     // caps outliers before the patch average
constexpr float kMinCenterWeight = 1e-4f;  // the centre pixel always counts
/// Tile side of the NL-means and regression loops (a multiple of the vector width).
constexpr int kTileSize = 32;

/// Scratch space for patch_distance on one tile.
struct DistanceScratch {
    std::vector<float> buffer, column_sum, row, inv_count_x;
    void reserve(int tile_size, int patch_radius)
    {
        size_t side = size_t(tile_size + 2 * patch_radius);
        buffer.resize(side * side);
        column_sum.resize(side);
        row.resize(tile_size);
        inv_count_x.resize(tile_size);
    }
};

/// Patch-averaged distance d²(p, p + (dx, dy)) for every p of `tile`, one channel: the mean
/// over the part of p's patch where both pixels lie inside the image (the box filter of
/// the reference implementation, normalised by the pixel count at the borders).
/// Written to out[(y - tile.y0) * stride + (x - tile.x0)]; with `take_max` the result is
/// max(out, d²) (the regression combines colour channels by their largest distance).
/// Pixels whose neighbour falls outside the image are left untouched: the caller fills
/// `out` with +inf first.
MCDN_INLINE void patch_distance(float* out, int stride, const float* guide, const float* variance,
                                int width, int height, Rect tile, int dx, int dy,
                                int patch_radius, float k, float variance_scale, bool take_max,
                                DistanceScratch& scratch)
{
    const int F = patch_radius;
    const int bx0 = tile.x0 - F, by0 = tile.y0 - F;
    const int bw = tile.width() + 2 * F, bh = tile.height() + 2 * F;
    // Pixels p of the patches with p and p + delta inside the image.
    const int qx0 = std::max(bx0, std::max(0, -dx)), qx1 = std::min(tile.x1 + F, std::min(width, width - dx));
    const int qy0 = std::max(by0, std::max(0, -dy)), qy1 = std::min(tile.y1 + F, std::min(height, height - dy));
    // Pixels p of the tile whose neighbour p + delta is inside the image.
    const int vx0 = std::max(tile.x0, -dx), vx1 = std::min(tile.x1, width - dx);
    const int vy0 = std::max(tile.y0, -dy), vy1 = std::min(tile.y1, height - dy);
    if (vx0 >= vx1 || vy0 >= vy1)
        return;

    float* buf = scratch.buffer.data();
    std::fill(buf, buf + size_t(bw) * bh, 0.0f);  // zero outside the valid part: box sums stay exact
    const float k2 = k * k;
    for (int y = qy0; y < qy1; ++y) {
        float* b = buf + size_t(y - by0) * bw + (qx0 - bx0);
        const float* gp = guide + size_t(y) * width + qx0;
        const float* gq = guide + size_t(y + dy) * width + qx0 + dx;
        const float* vp_row = variance + size_t(y) * width + qx0;
        const float* vq_row = variance + size_t(y + dy) * width + qx0 + dx;
        const int n = qx1 - qx0;
        for (int i = 0; i < n; ++i) {
            float vp = vp_row[i] * variance_scale, vq = vq_row[i] * variance_scale;
            float diff = gp[i] - gq[i];
            float num = diff * diff - (vp + std::min(vp, vq));
            float d = num / (kEpsilon + k2 * (vp + vq));
            b[i] = std::min(d, kDistanceClamp);
        }
    }

    float* colsum = scratch.column_sum.data();
    float* row = scratch.row.data();
    float* inv_cx = scratch.inv_count_x.data();
    const int nx = vx1 - vx0;
    for (int i = 0; i < nx; ++i) {
        int x = vx0 + i;
        inv_cx[i] = 1.0f / float(std::min(x + F + 1, qx1) - std::max(x - F, qx0));
    }
    for (int y = vy0; y < vy1; ++y) {
        // Vertical box sum of the 2F+1 rows around y, for every column of the buffer.
        const float* b = buf + size_t(y - F - by0) * bw;
        for (int i = 0; i < bw; ++i)
            colsum[i] = b[i];
        for (int j = 1; j <= 2 * F; ++j) {
            const float* bj = b + size_t(j) * bw;
            for (int i = 0; i < bw; ++i)
                colsum[i] += bj[i];
        }
        // Horizontal box sum, then divide by the number of valid patch pixels.
        const float* c = colsum + (vx0 - F - bx0);
        for (int i = 0; i < nx; ++i)
            row[i] = c[i];
        for (int j = 1; j <= 2 * F; ++j)
            for (int i = 0; i < nx; ++i)
                row[i] += c[i + j];
        const float inv_cy = 1.0f / float(std::min(y + F + 1, qy1) - std::max(y - F, qy0));
        float* o = out + size_t(y - tile.y0) * stride + (vx0 - tile.x0);
        if (take_max)
            for (int i = 0; i < nx; ++i)
                o[i] = std::max(o[i], row[i] * inv_cx[i] * inv_cy);
        else
            for (int i = 0; i < nx; ++i)
                o[i] = row[i] * inv_cx[i] * inv_cy;
    }
}

}  // namespace nlm

/// NL-means filter: channel c of `image` is filtered with the weights of channel
/// c % guide.size() of `guide` and `variance` (per-channel weights, as the reference).
/// All planes have the same size. Deterministic for any thread count.
std::vector<Plane> nl_means(const std::vector<const Plane*>& image,
                            const std::vector<const Plane*>& guide,
                            const std::vector<const Plane*>& variance, const NlMeansParams& params,
                            int nthreads);

}  // namespace mcdn
