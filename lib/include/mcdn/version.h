// The version of mcdenoise, and where the library finds what it ships beside it.
#pragma once

#include <string>

namespace mcdn {

/// The library's version, "MAJOR.MINOR.PATCH": CMake's project(VERSION) it was built with.
const char* version();

/// What a tool writes into the `Software` metadata of an image it made: "mcdenoise X.Y.Z".
std::string software_name();

/// Where the library looks for what is installed beside it. Everything is relative to the
/// library's own file (lib/libmcdenoise.so -> ../share/mcdenoise/ under any prefix, the same
/// in the build tree), never the source tree it was built from, so an installed or moved
/// tree keeps working. $MCDN_MODELS and $OCIO override models_dir and ocio_config.
struct InstallPaths {
    std::string library;      ///< the shared library's file
    std::string data_dir;     ///< <prefix>/share/mcdenoise
    std::string models_dir;   ///< $MCDN_MODELS, else data_dir/models
    std::string ocio_config;  ///< $OCIO, else data_dir/ocio/config.ocio
    std::string plugin_dir;   ///< the OIIO format plugin's folder (for OIIO_LIBRARY_PATH)
};
InstallPaths install_paths();

}  // namespace mcdn
