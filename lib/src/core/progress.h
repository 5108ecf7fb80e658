// Counting an op's units of work (tiles, bands, passes) into its ProgressCallback, and a
// chain's stages into one fraction of the whole run.
#pragma once

#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "mcdn/progress.h"

namespace mcdn {

class ProgressCounter {
public:
    ProgressCounter(const ProgressCallback& callback, std::string stage, int total)
        : m_callback(callback), m_stage(std::move(stage)), m_total(total > 0 ? total : 1)
    { }
    /// One more unit done (thread-safe); the callback hears of each new whole percent.
    /// False once it has cancelled: the op stops starting units and fails with error().
    bool advance(int units = 1)
    {
        if (!m_callback)
            return true;
        std::lock_guard<std::mutex> lock(m_mutex);
        m_done = std::min(m_total, m_done + units);
        const int percent = int(100.0 * m_done / m_total);
        if (percent != m_percent && !m_cancelled) {
            m_percent = percent;
            m_cancelled = m_callback(m_stage, float(m_done) / m_total);
        }
        return !m_cancelled;
    }
    /// advance() for a unit run beside others on workers: false once cancelled, with error()
    /// in `error` (under `guard`) unless a unit's own error is there already.
    bool advance(std::string& error, std::mutex& guard)
    {
        if (advance())
            return true;
        std::lock_guard<std::mutex> lock(guard);
        if (error.empty())
            error = this->error();
        return false;
    }
    std::string error() const { return m_stage + ": cancelled by the progress callback"; }

private:
    const ProgressCallback& m_callback;
    std::string m_stage;
    int m_total, m_done = 0, m_percent = -1;
    bool m_cancelled = false;
    std::mutex m_mutex;
};

/// The progress of a chain of `stages` as one fraction of the whole run, never decreasing:
/// stage k of the n reports (k + its fraction) / n, under its own name; a stage run again
/// inside a later one (the denoisers in SURE's probes) moves nothing back. Null for null.
inline ProgressCallback chain_progress(const ProgressCallback& callback,
                                       const std::vector<std::string>& stages)
{
    if (!callback || stages.empty())
        return callback;
    struct State {
        std::mutex mutex;
        size_t stage = 0;
        float last = 0;
    };
    auto state = std::make_shared<State>();
    return [callback, stages, state](const std::string& stage, float fraction) {
        std::lock_guard<std::mutex> lock(state->mutex);
        for (size_t k = state->stage; k < stages.size(); ++k)
            if (stages[k] == stage) {
                state->stage = k;
                state->last = std::max(state->last, (float(k) + fraction) / float(stages.size()));
                break;
            }
        return callback(stage, state->last);
    };
}

}  // namespace mcdn
