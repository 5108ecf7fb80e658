// Stage timing for every op (the benchmark's per-stage breakdown): with MCDN_TRACE set, each
// mark prints the wall and process CPU seconds since the previous mark to stderr, as
// "<op>: <stage> <wall> s wall <cpu> s CPU". Without it a mark costs one clock read.
#pragma once

#include <chrono>

namespace mcdn {

class StageTrace {
public:
    explicit StageTrace(const char* op);
    /// Ends the stage that began at the previous mark (or at construction).
    void mark(const char* stage);
    bool enabled() const { return m_on; }

private:
    const char* m_op;
    bool m_on;
    std::chrono::steady_clock::time_point m_last;
    double m_last_cpu = 0.0;
};

}  // namespace mcdn
