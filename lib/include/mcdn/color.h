// Colour management: every op runs in one declared working space, the scene_linear role of
// our OpenColorIO config (the space the networks were trained in: scene-linear Rec.709, what
// Blender and Tungsten write). Inputs in another space are converted in and the results back.
//
// Only the colour channels of the AOV set are converted: colour and its halves, albedo,
// diffuse/specular components, extras, and `noisy.*`. Variances transform with the squared
// matrix (Var[Mx]_i = sum_j M_ij^2 Var[x_j], channels taken as independent). Data channels
// (normal, depth, visibility) are never converted. Derived error channels that ops add
// (sure.*, nfor.mse.*, mix.alpha.*) stay in the working space.
#pragma once

#include <array>
#include <functional>
#include <string>

#include <OpenImageIO/imagebuf.h>

#include "mcdn/aov.h"

namespace mcdn {

/// The config: $OCIO when set, else the one installed with the library
/// (share/mcdenoise/ocio/config.ocio: install_paths() in mcdn/version.h).
std::string ocio_config_path();

/// The working space of every op: the config's scene_linear role.
std::string working_colorspace();

/// The space the input is in, and `why` (for -v): AovSpec::colorspace when set; else the
/// image's "oiio:ColorSpace" unless it only says "Linear" (OIIO's EXR reader tags every file
/// so); else EXR's `chromaticities`: Rec.709, ACES AP1 or AP0 primaries by the config's name,
/// other primaries (P3, XYZ, a camera's) as a space of their own, "primaries rx,ry gx,gy
/// bx,by wx,wy", converted by the matrix of those primaries to Rec.709 (white adapted to D65
/// by Bradford) and by OCIO from there; else the config's scene_linear role. False with
/// `error` naming the name and the config when a name is not in the config, the
/// chromaticities are no three primaries and a white, or the config cannot be read: nothing
/// falls back to the working space unsaid.
bool input_colorspace(std::string& name, std::string& why, const AovSpec& aovs,
                      const ImageSpec& image, std::string& error);
/// The same, the working space on error (for callers that checked it before).
std::string input_colorspace(const AovSpec& aovs, const ImageSpec& image);

/// The 3x3 matrix (row-major) of a scene-linear conversion; false with `error` when either
/// space is unknown or the transform is not linear (a display or log encoding).
bool linear_transform(std::array<double, 9>& matrix, const std::string& from, const std::string& to,
                      std::string& error);

/// Converts the colour channels of `aovs` in `buf` (a float buffer) from `from` to `to`.
/// A display or log encoding on either side (an 8-bit PNG's sRGB, linearised for the ops and
/// encoded again after them) is converted per pixel by OCIO, curve included; a variance has
/// no such conversion: false with `error`.
bool convert_color_channels(ImageBuf& buf, const AovSet& aovs, const std::string& from,
                            const std::string& to, std::string& error, int nthreads = 0);

/// Whether `image`, its colour in `from`, needs into_working_space: not converted already,
/// and another space or extras that hold light divided by a factor (Blender's light passes,
/// AovSet::Extra).
bool needs_working_conversion(const ImageSpec& image, const std::string& from, const AovSet& aovs);

/// What every op sees: the colour channels converted from `from` to the working space, and
/// each extra that holds light divided by a factor (Blender's DiffDir = light / DiffCol) as
/// light, factor × pass (before the conversion: the product is what adds up to the beauty),
/// so that the denoisers filter light and a comp rebuilt from the passes adds up to the
/// denoised beauty. Marks buf as converted (input_colorspace then says the working space).
/// On `nthreads` threads (0: every core), pixel by pixel: the same result for any number.
bool into_working_space(ImageBuf& buf, const AovSet& aovs, const std::string& from,
                        std::string& error, int nthreads = 0);
/// The way back: colour to `to`, then each factored extra divided by its factor again, by
/// Cycles' rule where a factor channel is (near) 0: the mean of the other channels' quotients.
bool out_of_working_space(ImageBuf& buf, const AovSet& aovs, const std::string& to,
                          std::string& error, int nthreads = 0);

/// Runs `op` in the working space: converts a copy of src in (into_working_space; when
/// needs_working_conversion says so), runs op, converts dst's channels back. The common case
/// (input already in the working space, no factored extras) costs nothing.
bool run_in_working_space(ImageBuf& dst, const ImageBuf& src, const AovSpec& aovs,
                          const char* op_name,
                          const std::function<bool(ImageBuf& dst, const ImageBuf& src)>& op);

}  // namespace mcdn
