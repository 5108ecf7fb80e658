// mcdn/version.h: the library's version and the folders it finds relative to its own file.
#include "mcdn/version.h"

#include <dlfcn.h>

#include <cstdlib>
#include <filesystem>

#if !defined(MCDN_LIB_TO_DATA) || !defined(MCDN_VERSION)
#    error "MCDN_LIB_TO_DATA (the data folder relative to the library's) and MCDN_VERSION: CMake"
#endif

namespace mcdn {

namespace fs = std::filesystem;

const char* version()
{
    return MCDN_VERSION;
}

std::string software_name()
{
    return std::string("mcdenoise ") + version();
}

namespace {

// The file this function's code was loaded from: the shared library (or, linked statically,
// the executable), through the links the loader followed, so a symlinked library still
// finds the data installed beside the real one.
fs::path library_file()
{
    Dl_info info {};
    if (!dladdr(reinterpret_cast<void*>(&library_file), &info) || !info.dli_fname)
        return {};
    std::error_code ec;
    fs::path path = fs::weakly_canonical(fs::absolute(info.dli_fname, ec), ec);
    return ec ? fs::path(info.dli_fname) : path;
}

std::string env_or(const char* name, const fs::path& fallback)
{
    const char* value = std::getenv(name);
    return value && *value ? std::string(value) : fallback.string();
}

}  // namespace

InstallPaths install_paths()
{
    static const fs::path lib = library_file();  // the library does not move while loaded
    const fs::path lib_dir = lib.parent_path();
    std::error_code ec;
    fs::path data = fs::weakly_canonical(lib_dir / MCDN_LIB_TO_DATA, ec);
    if (ec)
        data = (lib_dir / MCDN_LIB_TO_DATA).lexically_normal();
    InstallPaths paths;
    paths.library = lib.string();
    paths.data_dir = data.string();
    paths.models_dir = env_or("MCDN_MODELS", data / "models");
    paths.ocio_config = env_or("OCIO", data / "ocio" / "config.ocio");
    paths.plugin_dir = (lib_dir / "mcdenoise").string();
    return paths;
}

}  // namespace mcdn
