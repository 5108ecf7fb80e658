// Counter-based random numbers: the value for (seed, stream, index) never depends on which
// thread asks or in which order, so results are identical for any thread count.
#pragma once

#include <cmath>
#include <cstdint>

namespace mcdn {

/// SplitMix64's finaliser: a bijective 64-bit mix with good avalanche.
inline uint64_t mix64(uint64_t z)
{
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/// Uniform in (0, 1) for (seed, stream, index).
inline double uniform01(uint64_t seed, uint64_t stream, uint64_t index)
{
    uint64_t h = mix64(seed ^ mix64(stream * 0x9E3779B97F4A7C15ull ^ mix64(index)));
    return (double(h >> 11) + 0.5) * (1.0 / 9007199254740992.0);
}

/// Standard normal for (seed, stream, index), by Box-Muller on two uniforms.
inline float standard_normal(uint64_t seed, uint64_t stream, uint64_t index)
{
    double u1 = uniform01(seed, stream, 2 * index), u2 = uniform01(seed, stream, 2 * index + 1);
    return float(std::sqrt(-2.0 * std::log(u1)) * std::cos(6.283185307179586 * u2));
}

}  // namespace mcdn
