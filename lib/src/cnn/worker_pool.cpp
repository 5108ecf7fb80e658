#include "cnn/worker_pool.h"

#include <sys/stat.h>

#include <algorithm>
#include <mutex>
#include <thread>

#include "mcdn/cnn.h"

namespace mcdn {
namespace kpcn {

namespace {

/// Which weights a worker holds: a rewritten file (a new training step) is a new key.
struct Key {
    std::string path;
    long long size = -1, modified_ns = -1;
    int image_channels = 0;
    bool operator==(const Key& o) const
    {
        return path == o.path && size == o.size && modified_ns == o.modified_ns
               && image_channels == o.image_channels;
    }
};

Key key_of(const std::string& path, int image_channels)
{
    Key key { path, -1, -1, image_channels };
    struct stat st {};
    if (::stat(path.c_str(), &st) == 0) {
        key.size = st.st_size;
        key.modified_ns = (long long)st.st_mtim.tv_sec * 1000000000LL + st.st_mtim.tv_nsec;
    }
    return key;
}

struct Idle {
    Key key;
    std::unique_ptr<Worker> worker;
};

std::mutex pool_mutex;
std::vector<Idle>& idle_workers()
{
    static std::vector<Idle> pool;
    return pool;
}
// The key of each worker handed out, by address, so return_worker knows where it belongs.
std::vector<std::pair<const Worker*, Key>>& lent_workers()
{
    static std::vector<std::pair<const Worker*, Key>> lent;
    return lent;
}

}  // namespace

std::unique_ptr<Worker> take_worker(const std::string& path, int image_channels, std::string& error)
{
    const Key key = key_of(path, image_channels);
    std::unique_ptr<Worker> worker;
    {
        std::lock_guard<std::mutex> lock(pool_mutex);
        auto& pool = idle_workers();
        auto it = std::find_if(pool.begin(), pool.end(), [&](const Idle& i) { return i.key == key; });
        if (it != pool.end()) {
            worker = std::move(it->worker);
            pool.erase(it);
        }
    }
    if (!worker) {
        worker = std::make_unique<Worker>();
        if (!load_model(worker->model, path, error, image_channels))
            return nullptr;
    }
    std::lock_guard<std::mutex> lock(pool_mutex);
    lent_workers().emplace_back(worker.get(), key);
    return worker;
}

void return_worker(std::unique_ptr<Worker> worker)
{
    if (!worker)
        return;
    std::lock_guard<std::mutex> lock(pool_mutex);
    auto& lent = lent_workers();
    auto it = std::find_if(lent.begin(), lent.end(), [&](const auto& l) { return l.first == worker.get(); });
    if (it == lent.end())
        return;
    Key key = it->second;
    lent.erase(it);
    auto& pool = idle_workers();
    const size_t keep = std::max(1u, std::thread::hardware_concurrency());
    if (pool.size() >= keep)
        pool.erase(pool.begin());  // the longest idle goes
    pool.push_back({ std::move(key), std::move(worker) });
}

void release_workers()
{
    std::vector<Idle> freed;
    {
        std::lock_guard<std::mutex> lock(pool_mutex);
        freed.swap(idle_workers());
    }
}

}  // namespace kpcn

void release_cnn_workers() { kpcn::release_workers(); }

}  // namespace mcdn
