// The threads of the engine's own ops. Debian's oneDNN runs its convolutions on OpenMP, and
// its workers spin for a while after each convolution: ops on a second pool (TBB) between
// two convolutions then share the cores with those spinning threads (their CPU time goes to
// libgomp's spin loop). So the ops run on OpenMP too when the library is built with it (the
// same workers, already awake), and on TBB otherwise.
// Each row is computed by one thread: results never depend on the thread count.
#pragma once

#include <algorithm>
#include <exception>

#ifdef _OPENMP
#    include <omp.h>
#else
#    include <tbb/blocked_range.h>
#    include <tbb/parallel_for.h>
#endif

namespace mcdn {
namespace nn {

/// block(first, last) over blocks of rows covering [0, height) (a few rows each, handed
/// out dynamically: a shared machine does not stall on one slow thread); per-block scratch
/// lives in block().
template <class Block> void parallel_row_blocks(int height, Block block)
{
#ifdef _OPENMP
    // Inside nn::for_each_tile (one tile per worker) the rows stay on this worker.
    const bool nested = omp_in_parallel();
    const int rows = std::max(1, std::min(8, height / (4 * omp_get_max_threads())));
    // An exception (out of memory) cannot leave an OpenMP region: the first is thrown again
    // on this thread once the region ends.
    std::exception_ptr thrown;
#    pragma omp parallel for schedule(dynamic, 1) if (!nested)
    for (int first = 0; first < height; first += rows)
        try {
            block(first, std::min(first + rows, height));
        } catch (...) {
#    pragma omp critical(mcdn_parallel_row_blocks)
            if (!thrown)
                thrown = std::current_exception();
        }
    if (thrown)
        std::rethrow_exception(thrown);
#else
    tbb::parallel_for(tbb::blocked_range<int>(0, height),
                      [&](const tbb::blocked_range<int>& r) { block(r.begin(), r.end()); });
#endif
}

/// row(y) for every y in [0, height).
template <class Row> void parallel_rows(int height, Row row)
{
    parallel_row_blocks(height, [&](int first, int last) {
        for (int y = first; y < last; ++y)
            row(y);
    });
}

}  // namespace nn
}  // namespace mcdn
