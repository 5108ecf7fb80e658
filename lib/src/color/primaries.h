// Colour spaces by their primaries (primaries.cpp): an EXR's chromaticities as a space of
// its own, converted to and from linear Rec.709 by a 3x3 matrix, for the primaries our OCIO
// config has no space for (P3, XYZ, a camera's).
#pragma once

#include <array>
#include <string>

namespace mcdn {

// EXR's chromaticities (red, green, blue, white xy) of the primaries our config names.
struct Primaries {
    const char* colorspace;
    const char* name;
    float xy[8];
};
inline constexpr Primaries kPrimaries[] = {
    { "lin_rec709", "Rec.709", { 0.64f, 0.33f, 0.30f, 0.60f, 0.15f, 0.06f, 0.3127f, 0.3290f } },
    { "acescg",
      "ACES AP1",
      { 0.713f, 0.293f, 0.165f, 0.830f, 0.128f, 0.044f, 0.32168f, 0.33767f } },
    { "aces2065_1",
      "ACES AP0",
      { 0.7347f, 0.2653f, 0.0f, 1.0f, 0.0001f, -0.077f, 0.32168f, 0.33767f } },
};

// The space of an EXR's own primaries, by name: kPrimariesName then "rx,ry gx,gy bx,by wx,wy".
inline constexpr const char* kPrimariesName = "primaries ";

using Matrix = std::array<double, 9>;

/// The inverse of m; false when m is singular.
bool invert(Matrix& inv, const Matrix& m);

/// The matrix from the primaries named `name` (kPrimariesName ...) to linear Rec.709, white
/// adapted to D65 (Bradford).
bool primaries_to_rec709(Matrix& m, const std::string& name, std::string& error);

/// True when `name` names a space by its primaries (kPrimariesName ...).
bool is_primaries(const std::string& name);

}  // namespace mcdn
