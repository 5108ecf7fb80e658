// Where the benchmarks find generated evaluation crops: $MCDN_CACHE (default
// ~/.cache/mcdenoise)/datasets/eval when it exists, else datasets/full.
#pragma once

#include <cstdlib>
#include <filesystem>

namespace mcdn_bench {

/// The generated dataset to evaluate on; `is_eval` says whether it is the held-out set.
inline std::filesystem::path generated_dataset(bool& is_eval)
{
    namespace fs = std::filesystem;
    const char* cache_env = std::getenv("MCDN_CACHE");
    const char* home = std::getenv("HOME");
    const fs::path cache =
        cache_env ? fs::path(cache_env) : fs::path(home ? home : "/") / ".cache/mcdenoise";
    fs::path root = cache / "datasets/eval";
    is_eval = fs::exists(root);
    return is_eval ? root : cache / "datasets/full";
}

}  // namespace mcdn_bench
