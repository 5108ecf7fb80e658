#include "core/trace.h"

#include <cstdio>
#include <cstdlib>

#include <sys/resource.h>
#include <unistd.h>

namespace mcdn {
namespace {

/// Process CPU seconds, all threads (user + system: page clearing shows in the latter).
double process_cpu_seconds()
{
    rusage u {};
    getrusage(RUSAGE_SELF, &u);
    return u.ru_utime.tv_sec + u.ru_stime.tv_sec + 1e-6 * (u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

/// Resident memory now, in GB (peak memory is the sum of what is alive at once).
double resident_gb()
{
    long pages = 0, resident = 0;
    if (FILE* f = std::fopen("/proc/self/statm", "r")) {
        if (std::fscanf(f, "%ld %ld", &pages, &resident) != 2)
            resident = 0;
        std::fclose(f);
    }
    return double(resident) * double(sysconf(_SC_PAGESIZE)) / 1e9;
}

}  // namespace

StageTrace::StageTrace(const char* op)
    : m_op(op), m_on(std::getenv("MCDN_TRACE") != nullptr), m_last(std::chrono::steady_clock::now())
{
    if (m_on)
        m_last_cpu = process_cpu_seconds();
}

void StageTrace::mark(const char* stage)
{
    auto now = std::chrono::steady_clock::now();
    if (m_on) {
        double cpu = process_cpu_seconds();
        std::fprintf(stderr, "%s: %-28s %7.3f s wall %7.3f s CPU %6.2f GB resident\n", m_op, stage,
                     std::chrono::duration<double>(now - m_last).count(), cpu - m_last_cpu,
                     resident_gb());
        m_last_cpu = cpu;
    }
    m_last = now;
}

}  // namespace mcdn
