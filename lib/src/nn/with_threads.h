// The thread count of a network op (the cnn's, the oidn's): its own ops on TBB, oneDNN's
// convolutions on OpenMP.
#pragma once

#include <dlfcn.h>

#include <tbb/task_arena.h>

namespace mcdn {
namespace nn {

/// Runs `body` on at most `nthreads` threads (0 = all): a TBB arena for our ops, and the
/// OpenMP thread count of this thread for oneDNN's convolutions (looked up at run time, as
/// only oneDNN links OpenMP; absent with a TBB-threaded oneDNN, where the arena suffices).
/// No result depends on the count: every output value is computed by one thread.
template <class Body> bool with_threads(int nthreads, Body&& body)
{
    if (nthreads <= 0)
        return body();
    using SetThreads = void (*)(int);
    using GetThreads = int (*)();
    auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "omp_set_num_threads"));
    auto get = reinterpret_cast<GetThreads>(dlsym(RTLD_DEFAULT, "omp_get_max_threads"));
    const int previous = set && get ? get() : 0;
    if (set && get)
        set(nthreads);
    bool ok = false;
    tbb::task_arena arena(nthreads);
    arena.execute([&] { ok = body(); });
    if (set && get)
        set(previous);
    return ok;
}

}  // namespace nn
}  // namespace mcdn
