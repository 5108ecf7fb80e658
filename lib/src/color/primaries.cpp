// Colour spaces by their primaries (primaries.h): RGB to XYZ from the primaries and white,
// Bradford's adaptation of the white to D65, then XYZ to linear Rec.709.
#include "color/primaries.h"

#include <cmath>
#include <cstdio>
#include <cstring>

#include <OpenImageIO/strutil.h>

namespace mcdn {

using OIIO::Strutil::fmt::format;

namespace {

Matrix multiply(const Matrix& a, const Matrix& b)
{
    Matrix m {};
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j)
            for (int k = 0; k < 3; ++k)
                m[i * 3 + j] += a[i * 3 + k] * b[k * 3 + j];
    return m;
}

// RGB -> XYZ of primaries and white (xy each): the primaries' xyz columns scaled so that
// RGB (1,1,1) is the white at Y = 1 (no division by a primary's y: XYZ's own have y = 0).
bool rgb_to_xyz(Matrix& m, const float xy[8])
{
    const Matrix p = { xy[0],
                       xy[2],
                       xy[4],
                       xy[1],
                       xy[3],
                       xy[5],
                       1.0 - xy[0] - xy[1],
                       1.0 - xy[2] - xy[3],
                       1.0 - xy[4] - xy[5] };
    Matrix inv;
    if (!invert(inv, p) || !(xy[7] > 0))
        return false;
    const double w[3] = { xy[6] / xy[7], 1.0, (1.0 - xy[6] - xy[7]) / xy[7] };
    for (int j = 0; j < 3; ++j) {
        const double scale = inv[j * 3] * w[0] + inv[j * 3 + 1] * w[1] + inv[j * 3 + 2] * w[2];
        for (int i = 0; i < 3; ++i)
            m[i * 3 + j] = p[i * 3 + j] * scale;
    }
    return true;
}

// Bradford's chromatic adaptation between two whites (xy), in XYZ.
Matrix bradford(const float from[2], const float to[2])
{
    const Matrix b = { 0.8951, 0.2664, -0.1614, -0.7502, 1.7135, 0.0367, 0.0389, -0.0685, 1.0296 };
    Matrix b_inv;
    invert(b_inv, b);
    auto cone = [&](const float xy[2]) {
        const double w[3] = { xy[0] / xy[1], 1.0, (1.0 - xy[0] - xy[1]) / xy[1] };
        std::array<double, 3> c {};
        for (int i = 0; i < 3; ++i)
            c[i] = b[i * 3] * w[0] + b[i * 3 + 1] * w[1] + b[i * 3 + 2] * w[2];
        return c;
    };
    const auto s = cone(from), d = cone(to);
    Matrix scale = { d[0] / s[0], 0, 0, 0, d[1] / s[1], 0, 0, 0, d[2] / s[2] };
    return multiply(b_inv, multiply(scale, b));
}

}  // namespace

bool invert(Matrix& inv, const Matrix& m)
{
    const double det = m[0] * (m[4] * m[8] - m[5] * m[7]) - m[1] * (m[3] * m[8] - m[5] * m[6])
                       + m[2] * (m[3] * m[7] - m[4] * m[6]);
    if (!(std::fabs(det) > 1e-12))
        return false;
    inv = { (m[4] * m[8] - m[5] * m[7]) / det, (m[2] * m[7] - m[1] * m[8]) / det,
            (m[1] * m[5] - m[2] * m[4]) / det, (m[5] * m[6] - m[3] * m[8]) / det,
            (m[0] * m[8] - m[2] * m[6]) / det, (m[2] * m[3] - m[0] * m[5]) / det,
            (m[3] * m[7] - m[4] * m[6]) / det, (m[1] * m[6] - m[0] * m[7]) / det,
            (m[0] * m[4] - m[1] * m[3]) / det };
    return true;
}

bool primaries_to_rec709(Matrix& m, const std::string& name, std::string& error)
{
    float xy[8];
    if (std::sscanf(name.c_str() + std::strlen(kPrimariesName), "%f,%f %f,%f %f,%f %f,%f", &xy[0],
                    &xy[1], &xy[2], &xy[3], &xy[4], &xy[5], &xy[6], &xy[7])
        != 8) {
        error = format("'{}' is no set of primaries", name);
        return false;
    }
    Matrix src, rec709, rec709_inv;
    if (!rgb_to_xyz(src, xy)) {
        error = format("the file's chromaticities (red {},{} green {},{} blue {},{} white {},{}) "
                       "are not three primaries and a white: give --aov:colorspace=NAME",
                       xy[0], xy[1], xy[2], xy[3], xy[4], xy[5], xy[6], xy[7]);
        return false;
    }
    rgb_to_xyz(rec709, kPrimaries[0].xy);
    invert(rec709_inv, rec709);
    m = multiply(rec709_inv, multiply(bradford(xy + 6, kPrimaries[0].xy + 6), src));
    return true;
}

bool is_primaries(const std::string& name)
{
    return OIIO::Strutil::starts_with(name, kPrimariesName);
}

}  // namespace mcdn
