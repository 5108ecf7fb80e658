// Counting an op's units of work (tiles, bands, passes) into its ProgressCallback.
#pragma once

#include <mutex>
#include <string>

#include "mcdn/progress.h"

namespace mcdn {

class ProgressCounter {
public:
    ProgressCounter(const ProgressCallback& callback, std::string stage, int total)
        : m_callback(callback), m_stage(std::move(stage)), m_total(total > 0 ? total : 1)
    { }
    /// One more unit done (thread-safe); the callback hears of each new whole percent.
    void advance(int units = 1)
    {
        if (!m_callback)
            return;
        std::lock_guard<std::mutex> lock(m_mutex);
        m_done = std::min(m_total, m_done + units);
        const int percent = int(100.0 * m_done / m_total);
        if (percent != m_percent) {
            m_percent = percent;
            m_callback(m_stage, float(m_done) / m_total);
        }
    }

private:
    const ProgressCallback& m_callback;
    std::string m_stage;
    int m_total, m_done = 0, m_percent = -1;
    std::mutex m_mutex;
};

}  // namespace mcdn
