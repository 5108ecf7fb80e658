#include "ops/window_sums.h"

#include <algorithm>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace mcdn {

namespace {

/// One pass along a line of `n` values `at(k)`: out[k] = the (divided) sum of
/// taps[i + r] * at(k + i) over the in-range i, in increasing i. The taps loop runs outside
/// the pixel loop, so the pixels' sums are independent (vectorisable) while each keeps its
/// own order.
template <class At>
void window_line(int n, const std::vector<double>& taps, int r, bool mean, At at,
                 std::vector<double>& sum, float* out, size_t out_step)
{
    sum.assign(size_t(n), 0.0);
    for (int i = -r; i <= r; ++i) {
        const double t = taps[size_t(i + r)];
        const int first = std::max(0, -i), last = std::min(n, n - i);
        for (int k = first; k < last; ++k)
            sum[size_t(k)] += t * at(k + i);
    }
    for (int k = 0; k < n; ++k) {
        const double count = std::min(n - 1, k + r) - std::max(0, k - r) + 1;
        out[size_t(k) * out_step] = float(mean ? sum[size_t(k)] / count : sum[size_t(k)]);
    }
}

template <class Row> void for_rows(int height, Row row)
{
    tbb::parallel_for(tbb::blocked_range<int>(0, height), [&](const tbb::blocked_range<int>& b) {
        for (int y = b.begin(); y != b.end(); ++y)
            row(y);
    });
}

}  // namespace

Plane separable_window_sum(const Plane& in, const std::vector<double>& taps, int radius, bool mean)
{
    const int w = in.width, h = in.height;
    Plane rows(w, h), out(w, h);
    for_rows(h, [&](int y) {
        thread_local std::vector<double> sum;
        const float* line = in.row(y);
        window_line(
            w, taps, radius, mean, [line](int x) { return double(line[x]); }, sum,
            rows.px.data() + size_t(y) * w, 1);
    });
    // Columns: blocks of whole columns, each a pass down them, summed across the block's
    // pixels at once (row by row: contiguous reads).
    constexpr int kBlock = 256;
    tbb::parallel_for(tbb::blocked_range<int>(0, (w + kBlock - 1) / kBlock),
                      [&](const tbb::blocked_range<int>& b) {
                          std::vector<double> sum;
                          for (int block = b.begin(); block != b.end(); ++block) {
                              const int x0 = block * kBlock, n = std::min(kBlock, w - x0);
                              for (int y = 0; y < h; ++y) {
                                  sum.assign(size_t(n), 0.0);
                                  const int first = std::max(0, y - radius),
                                            last = std::min(h - 1, y + radius);
                                  for (int j = first; j <= last; ++j) {
                                      const double t = taps[size_t(j - y + radius)];
                                      const float* line = rows.row(j) + x0;
                                      for (int k = 0; k < n; ++k)
                                          sum[size_t(k)] += t * double(line[k]);
                                  }
                                  float* o = out.row(y) + x0;
                                  const double count = last - first + 1;
                                  for (int k = 0; k < n; ++k)
                                      o[k] = float(mean ? sum[size_t(k)] / count : sum[size_t(k)]);
                              }
                          }
                      });
    return out;
}

}  // namespace mcdn
