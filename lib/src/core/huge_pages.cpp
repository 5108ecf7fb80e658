#include "core/huge_pages.h"

#include <cstdint>

#if defined(__linux__)
#    include <sys/mman.h>
#endif

namespace mcdn {

void advise_huge_pages(void* data, size_t bytes)
{
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    // The whole 2 MB pages inside the buffer (madvise wants page-aligned ranges; a huge
    // page can only back an aligned 2 MB of it).
    constexpr uintptr_t huge = uintptr_t(2) << 20;
    const uintptr_t first = (reinterpret_cast<uintptr_t>(data) + huge - 1) / huge * huge;
    const uintptr_t last = (reinterpret_cast<uintptr_t>(data) + bytes) / huge * huge;
    if (last > first)
        madvise(reinterpret_cast<void*>(first), last - first,
                MADV_HUGEPAGE);  // errors are harmless
#else
    (void)data;
    (void)bytes;
#endif
}

}  // namespace mcdn
