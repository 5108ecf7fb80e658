// PD eq. 12-18: bound alpha by a t-test so the mix converges to the render.
//
// Around each pixel p, Gaussian-weighted sums over the 11x11 neighbourhood N_p, plus the
// neighbour M_p of highest variance counted once more (it guards against variance that is
// underestimated at low sample counts):
//   x-bar - z-bar = d_M + sum kappa d_q,        d = alpha (y - x)
//   Var[x-bar]    = Var_M + sum kappa^2 Var_q
//   t = (z-bar - x-bar) / (sqrt(Var[x-bar]) + eps);  alpha' = (1 - Phi(a (|t| - c))) alpha
// kappa (eq. 15) is the paper's unnormalised 1/(sigma_s sqrt(2 pi)) exp(-|p-q|^2 / 2 sigma_s^2).
// It is separable, so each sum is a row pass and a column pass. Every pass is threaded
// over rows, each value computed by one thread: the result does not depend on the count.
#include <cmath>
#include <vector>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "ops/bands.h"
#include "core/frame_facts.h"
#include "mix/mix_steps.h"
#include "ops/window_sums.h"

namespace mcdn {

namespace {

/// row(y) for every y in [0, height), on TBB's threads.
template <class Row> void for_rows(int height, Row row)
{
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& r) {
        for (int y = r.begin(); y != r.end(); ++y)
            row(y);
    });
}

// Eq. 16: for each pixel, the flat index of its highest-variance neighbour (first in raster
// order on ties), by a row pass and a column pass.
std::vector<size_t> highest_variance_neighbour(const Plane& variance, int radius)
{
    const int w = variance.width, h = variance.height;
    std::vector<int> row_best(size_t(w) * h);
    for_rows(h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            int best = std::max(0, x - radius);
            for (int i = best + 1; i <= std::min(w - 1, x + radius); ++i)
                if (variance(i, y) > variance(best, y))
                    best = i;
            row_best[size_t(y) * w + x] = best;
        }
    });
    std::vector<size_t> best(size_t(w) * h);
    for_rows(h, [&](int y) {
        for (int x = 0; x < w; ++x) {
            int by = std::max(0, y - radius);
            for (int j = by + 1; j <= std::min(h - 1, y + radius); ++j)
                if (variance(row_best[size_t(j) * w + x], j)
                    > variance(row_best[size_t(by) * w + x], by))
                    by = j;
            best[size_t(y) * w + x] = size_t(by) * w + row_best[size_t(by) * w + x];
        }
    });
    return best;
}

}  // namespace

float t_test_sigma(const OIIO::ImageBuf& src, const int x_channels[3], float scale)
{
    FrameFacts facts;  // a band of a larger frame: the frame's sigma_s
    return t_test_sigma(
        frame_facts(facts, src.spec()) ? facts.color : color_sums(src, x_channels, nullptr), scale);
}

void t_test_bound(Plane& alpha, const Plane& x, const Plane& y, const Plane& variance,
                  float sigma_s, const MixOptions& o)
{
    const int r = o.t_radius;
    const double sigma = std::max(double(sigma_s), 1e-3);
    std::vector<double> kappa(2 * r + 1), kappa2(2 * r + 1);
    for (int i = -r; i <= r; ++i) {
        // The 2D kernel of eq. 15 is the product of these; its 1/(sigma sqrt(2 pi)) factor
        // is split as a square root per axis, and squared for the variance sum.
        double k =
            std::exp(-0.5 * i * i / (sigma * sigma)) / std::sqrt(sigma * std::sqrt(2 * M_PI));
        kappa[i + r] = k;
        kappa2[i + r] = k * k;
    }
    Plane d(x.width, x.height);
    for (size_t i = 0; i < d.size(); ++i)
        d.px[i] = alpha.px[i] * (y.px[i] - x.px[i]);
    Plane d_sum = separable_window_sum(d, kappa, r);
    Plane var_sum = separable_window_sum(variance, kappa2, r);
    std::vector<size_t> m = highest_variance_neighbour(variance, r);
    for_rows(x.height, [&](int row) {
        for (size_t i = size_t(row) * x.width; i < size_t(row + 1) * x.width; ++i) {
            double difference = double(d.px[m[i]]) + d_sum.px[i];
            double var = double(variance.px[m[i]]) + var_sum.px[i];
            double t = difference / (std::sqrt(std::max(var, 0.0)) + o.t_epsilon);
            double u = o.t_strength * (std::fabs(t) - o.t_shift);
            double phi = 0.5 * std::erfc(-u / std::sqrt(2.0));  // standard normal CDF
            alpha.px[i] = float((1.0 - phi) * alpha.px[i]);
        }
    });
}

}  // namespace mcdn
