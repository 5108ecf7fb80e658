// Cycles' transmission passes (TransCol, TransDir, TransInd) have no role of their own
// (mcdn/aov.h): they sit beside DiffCol in the same view layer, named as it is with "Trans"
// for "Diff". The CNN's specular variance reads them (cnn/cnn_inputs.cpp), so the reader's
// role selection (io/io.cpp) must read their faces too.
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/strutil.h>

namespace mcdn {

constexpr const char* kTransmissionPasses[3] = { "TransCol", "TransDir", "TransInd" };

/// The channels of transmission pass `pass` beside the DiffCol channels `diffcol`.
inline std::vector<std::string> transmission_channels(const std::vector<std::string>& diffcol,
                                                      const char* pass)
{
    std::vector<std::string> out;
    for (const std::string& name : diffcol)
        out.push_back(OIIO::Strutil::replace(name, "DiffCol", pass));
    return out;
}

}  // namespace mcdn
