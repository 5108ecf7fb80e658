#include "mcdn/threads.h"

#include <OpenImageIO/strutil.h>

namespace mcdn {

namespace {

std::string range_error(const std::string& typed)
{
    return OIIO::Strutil::fmt::format(
        "threads={}: needs a whole number from 0 (all cores) to {}", typed, kMaxThreads);
}

}  // namespace

bool check_threads(int nthreads, std::string& error)
{
    if (nthreads >= 0 && nthreads <= kMaxThreads)
        return true;
    error = range_error(std::to_string(nthreads));
    return false;
}

bool parse_threads(const std::string& text, int& nthreads, std::string& error)
{
    bool digits = !text.empty() && text.size() <= 9
                  && text.find_first_not_of("0123456789") == std::string::npos;
    if (!digits || OIIO::Strutil::stoi(text) > kMaxThreads) {
        error = range_error(text);
        return false;
    }
    nthreads = OIIO::Strutil::stoi(text);
    return true;
}

}  // namespace mcdn
