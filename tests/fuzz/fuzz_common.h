// Helpers shared by the libFuzzer targets: the fuzzer's bytes as lines.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace mcdn_fuzz {

/// The input split at '\n' (a trailing newline adds no empty line); at most `max_lines`,
/// so one input cannot make a run quadratic in its length.
inline std::vector<std::string> lines_of(const uint8_t* data, size_t size, size_t max_lines = 64)
{
    std::vector<std::string> lines;
    std::string current;
    for (size_t i = 0; i < size && lines.size() < max_lines; ++i) {
        if (data[i] == '\n') {
            lines.push_back(current);
            current.clear();
        } else
            current += char(data[i]);
    }
    if (!current.empty() && lines.size() < max_lines)
        lines.push_back(current);
    return lines;
}

}  // namespace mcdn_fuzz
