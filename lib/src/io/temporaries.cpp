// The temporaries every write goes through (mcdn/io.h write_image): their names, the
// slots a signal handler removes them from, and the removal of those a dead writer left.
#include "mcdn/io.h"

#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <filesystem>

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/strutil.h>

#include "io/io_steps.h"

namespace mcdn {

namespace Filesystem = OIIO::Filesystem;
using OIIO::Strutil::fmt::format;

namespace {

namespace fs = std::filesystem;

// The temporary files of the writes in progress, for remove_temporary_outputs() in a signal
// handler: fixed slots (no allocation there), each free, being filled, or armed.
struct TemporarySlot {
    std::atomic<int> state { 0 };  // 0 free, 1 being filled, 2 armed
    char path[4096];
};
TemporarySlot g_temporaries[64];

// `.NAME.mcdn-tmp-` in the folder of `path`: what every temporary of that output starts with.
std::string temporary_prefix(const std::string& path)
{
    fs::path p(path);
    return (p.parent_path() / ("." + p.filename().string() + ".mcdn-tmp-")).string();
}

// How long a temporary nobody can be shown to own is left alone: a writer on another host
// (or in another container) touches its file at least once a band, far more often.
constexpr auto kStaleTemporaryAge = std::chrono::hours(24);

// Removes the temporaries of `path` that a dead writer left: what SIGKILL, a power cut or a
// crash left behind. A temporary's name holds its writer's PID and temporary_owner(); a PID
// is only checked where it means this host's process, in this PID namespace (on shared
// storage another node's or another container's PID names nothing here: its live writer
// would lose its work). A temporary of another owner, or an unowned one, goes only when it
// has not been written for kStaleTemporaryAge.
void remove_stale_temporaries(const std::string& path)
{
    const std::string prefix = temporary_prefix(path);
    const fs::path dir = fs::path(prefix).parent_path();
    const std::string start = fs::path(prefix).filename().string();
    const std::string owner = temporary_owner();
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir.empty() ? fs::path(".") : dir, ec)) {
        std::string name = entry.path().filename().string();
        if (name.compare(0, start.size(), start) != 0)
            continue;
        // PID-N-OWNER
        const char* text = name.c_str() + start.size();
        char* end = nullptr;
        const long pid = std::strtol(text, &end, 10);
        if (*end == '-')
            std::strtol(end + 1, &end, 10);
        const bool ours = *end == '-' && owner == end + 1;
        bool stale = false;
        if (ours)
            stale =
                pid > 0 && pid != long(::getpid()) && ::kill(pid_t(pid), 0) != 0 && errno == ESRCH;
        else {
            const auto written = fs::last_write_time(entry.path(), ec);
            stale = !ec && fs::file_time_type::clock::now() - written > kStaleTemporaryAge;
        }
        if (stale)
            fs::remove(entry.path(), ec);
    }
}

}  // namespace

TemporaryRegistration::TemporaryRegistration(const std::string& path)
{
    if (path.size() >= sizeof(TemporarySlot::path))
        return;
    for (auto& slot : g_temporaries) {
        int expected = 0;
        if (slot.state.compare_exchange_strong(expected, 1)) {
            std::memcpy(slot.path, path.c_str(), path.size() + 1);
            slot.state.store(2);
            m_slot = &slot;
            return;
        }
    }
}

TemporaryRegistration::~TemporaryRegistration()
{
    if (m_slot)
        static_cast<TemporarySlot*>(m_slot)->state.store(0);
}

const std::string& temporary_owner()
{
    static const std::string owner = [] {
        char host[256] = {};
        ::gethostname(host, sizeof(host) - 1);
        std::string name;
        for (const char* c = host; *c; ++c)
            name +=
                std::isalnum(static_cast<unsigned char>(*c)) || *c == '.' || *c == '_' ? *c : '_';
        // "pid:[4026531836]": the namespace's inode, the same for every process in it.
        char link[64] = {};
        std::string ns = "0";
        if (::readlink("/proc/self/ns/pid", link, sizeof(link) - 1) > 0) {
            std::string text(link);
            size_t open = text.find('['), close = text.find(']');
            if (open != std::string::npos && close != std::string::npos)
                ns = text.substr(open + 1, close - open - 1);
        }
        return format("{}-{}", ns, name.empty() ? "host" : name);
    }();
    return owner;
}

void remove_temporary_outputs()
{
    for (auto& slot : g_temporaries)
        if (slot.state.load() == 2)
            ::unlink(slot.path);
}

std::string temporary_for(const std::string& path)
{
    static std::atomic<int> counter { 0 };
    // The output's folder is made here, as the first file goes into it (mkdir -p, Blender's
    // and Nuke's Write do too): check_output_path made sure it can be.
    const std::filesystem::path dir = std::filesystem::path(path).parent_path();
    std::error_code ec;
    if (!dir.empty())
        std::filesystem::create_directories(dir, ec);
    remove_stale_temporaries(path);
    return format("{}{}-{}-{}", temporary_prefix(path), ::getpid(), counter++, temporary_owner());
}

bool put_in_place(const std::string& tmp, const std::string& path, std::string& error)
{
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode))
        ::chmod(tmp.c_str(), st.st_mode & 07777);
    std::string rename_error;
    if (!Filesystem::rename(tmp, path, rename_error)) {
        error = format("{}: cannot rename temporary file into place: {}", path, rename_error);
        Filesystem::remove(tmp);
        return false;
    }
    return true;
}

}  // namespace mcdn
