#include "cnn/worker_pool.h"

#include <sys/stat.h>

#include <algorithm>
#include <mutex>
#include <thread>

#include "mcdn/cnn.h"

namespace mcdn {
namespace kpcn {

namespace {

/// Which weights a worker holds: a rewritten file (a new training step) is another key.
std::string key_of(const std::string& path, int image_channels)
{
    struct stat st { };
    long long size = -1, modified_ns = -1;
    if (::stat(path.c_str(), &st) == 0) {
        size = st.st_size;
        modified_ns = (long long)st.st_mtim.tv_sec * 1000000000LL + st.st_mtim.tv_nsec;
    }
    return path + "|" + std::to_string(size) + "|" + std::to_string(modified_ns) + "|"
           + std::to_string(image_channels);
}

std::mutex pool_mutex;
std::vector<std::unique_ptr<Worker>>& idle_workers()
{
    static std::vector<std::unique_ptr<Worker>> pool;
    return pool;
}

}  // namespace

std::unique_ptr<Worker> take_worker(const std::string& path, int image_channels, std::string& error)
{
    const std::string key = key_of(path, image_channels);
    {
        std::lock_guard<std::mutex> lock(pool_mutex);
        auto& pool = idle_workers();
        auto it = std::find_if(pool.begin(), pool.end(),
                               [&](const auto& w) { return w->weights_key == key; });
        if (it != pool.end()) {
            std::unique_ptr<Worker> worker = std::move(*it);
            pool.erase(it);
            return worker;
        }
    }
    auto worker = std::make_unique<Worker>();
    if (!load_model(worker->model, path, error, image_channels))
        return nullptr;
    worker->weights_key = key;
    return worker;
}

void return_worker(std::unique_ptr<Worker> worker)
{
    if (!worker)
        return;
    std::lock_guard<std::mutex> lock(pool_mutex);
    auto& pool = idle_workers();
    const size_t keep = std::max(1u, std::thread::hardware_concurrency());
    if (pool.size() >= keep)
        pool.erase(pool.begin());  // the longest idle goes
    pool.push_back(std::move(worker));
}

void release_workers()
{
    std::vector<std::unique_ptr<Worker>> freed;
    std::lock_guard<std::mutex> lock(pool_mutex);
    freed.swap(idle_workers());
}

}  // namespace kpcn

void release_cnn_workers()
{
    kpcn::release_workers();
}

}  // namespace mcdn
