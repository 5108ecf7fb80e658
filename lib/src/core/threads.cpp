#include "mcdn/threads.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <thread>

#include <OpenImageIO/strutil.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#if defined(_OPENMP)
#    include <omp.h>
#endif

namespace mcdn {

namespace {

std::string range_error(const std::string& typed)
{
    return OIIO::Strutil::fmt::format("threads={}: needs a whole number from 0 (all cores) to {}",
                                      typed, kMaxThreads);
}

}  // namespace

bool check_threads(int nthreads, std::string& error)
{
    if (nthreads >= 0 && nthreads <= kMaxThreads)
        return true;
    error = range_error(std::to_string(nthreads));
    return false;
}

void start_threads(int nthreads)
{
    // TBB never runs more threads at once than the machine has cores, whatever an arena
    // asks for.
    const int cores = tbb::this_task_arena::max_concurrency();
    const int n = nthreads > 0 ? std::min(nthreads, cores) : cores;
    // A task per thread, each waiting (0.2 s at most) until all have started: every worker
    // runs one, so TBB has created them all.
    std::atomic<int> started { 0 };
    tbb::task_arena arena(n);
    arena.execute([&] {
        tbb::parallel_for(0, n, [&](int) {
            ++started;
            const auto until = std::chrono::steady_clock::now() + std::chrono::milliseconds(200);
            while (started.load() < n && std::chrono::steady_clock::now() < until)
                std::this_thread::yield();
        });
    });
#if defined(_OPENMP)
    // The network engine's (nn/parallel.h): libgomp keeps its pool once made.
#    pragma omp parallel num_threads(n)
    {
        (void)omp_get_thread_num();
    }
#endif
}

bool parse_threads(const std::string& text, int& nthreads, std::string& error)
{
    bool digits = !text.empty() && text.size() <= 9
                  && text.find_first_not_of("0123456789") == std::string::npos;
    if (!digits || OIIO::Strutil::stoi(text) > kMaxThreads) {
        error = range_error(text);
        return false;
    }
    nthreads = OIIO::Strutil::stoi(text);
    return true;
}

}  // namespace mcdn
