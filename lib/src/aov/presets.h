// The presets' channel names: where a renderer writes each role (aov.cpp resolves them).
#pragma once

#include <array>
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

/// The signs that make `preset`'s motion role (4 channels: towards the previous frame x, y;
/// towards the next x, y) displacements in pixels with rows going down (ops/motion.h):
/// Blender's Vector pass (X, Y, Z, W), also any preset's `--aov motion=`, (+, -, -, +);
/// RenderMan's backward.x, .y, forward.x, .y (raster space, y down) as they are.
std::array<float, 4> preset_motion_signs(const std::string& preset);

/// Where `preset` writes the `face` of `base` into the render file itself (a variance AOV),
/// besides the input-kind prefix of a separate file; empty where it writes none.
Candidates preset_face_candidates(const std::string& preset, Role base, Face face);

/// A light pass a renderer writes beside the beauty, denoised with it as an extra AOV
/// (AovSet::Extra): the channel names to try, and the names of the colour pass its light was
/// divided by (empty: the pass is light).
struct LightPass {
    Candidates names;
    std::vector<std::string> factor;
    std::string partition;  // AovSet::Extra::partition
};

/// The light passes of `preset` (Cycles: in view layer `layer`).
std::vector<LightPass> preset_light_passes(const std::string& preset, const std::string& layer);

/// The factor's channel names of a Cycles light pass named by `names` ("<layer>.DiffDir.R",
/// ...: DiffCol for DiffDir and DiffInd, GlossCol, TransCol); empty for any other channels.
std::vector<std::string> cycles_light_factor(const std::vector<std::string>& names);

}  // namespace mcdn
