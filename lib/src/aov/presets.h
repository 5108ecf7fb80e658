// The presets' channel names: where a renderer writes each role (aov.cpp resolves them).
#pragma once

#include <string>
#include <vector>

#include "mcdn/aov.h"

namespace mcdn {

/// stem.R, stem.G, stem.B for suffixes "RGB".
std::vector<std::string> with_suffixes(const std::string& stem, const char* suffixes);

/// Channel-name lists to try in order.
using Candidates = std::vector<std::vector<std::string>>;

/// Where `preset` keeps the mean face of `role` (Cycles: in view layer `layer`).
Candidates preset_candidates(const std::string& preset, const std::string& layer, Role role);

/// Where `preset` writes the `face` of `base` into the render file itself (a variance AOV),
/// besides the input-kind prefix of a separate file; empty where it writes none.
Candidates preset_face_candidates(const std::string& preset, Role base, Face face);

}  // namespace mcdn
