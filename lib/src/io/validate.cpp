// Checking the values the ops will read (mcdn/io.h validate_inputs): what no render holds
// is an error naming the file, the channel and the pixel, before any stage runs.
#include "mcdn/io.h"

#include <cmath>

#include <OpenImageIO/strutil.h>

#include "core/planar.h"
#include "io/io_steps.h"

namespace mcdn {

static_assert(kHugeValue == kMaxMagnitude,
              "validation refuses exactly what the ops would otherwise clamp");

using OIIO::TypeDesc;
using OIIO::Strutil::fmt::format;

bool check_color_faces(const ImageSpec& spec, const AovSet& aovs, bool halves, std::string& error)
{
    for (const InputFile& file : merged_input_files(spec)) {
        if (file.kind == InputKind::Mean || (!halves && file.kind != InputKind::Variance))
            continue;
        const Role role = file.kind == InputKind::Variance ? Role::ColorVariance
                          : file.kind == InputKind::HalfA  ? Role::ColorA
                                                           : Role::ColorB;
        std::string why;
        if (!aovs.require({ role }, spec, why)) {
            error = format("{}: given with -i:as={} but has no {} of the colour: {}", file.path,
                           input_kind_name(file.kind),
                           file.kind == InputKind::Variance ? "variance" : "half buffer", why);
            return false;
        }
    }
    return true;
}

bool validate_inputs(const ImageBuf& merged, const AovSet& aovs, std::string& error)
{
    const ImageSpec& spec = merged.spec();
    const int nch = spec.nchannels;
    const float* pixels = static_cast<const float*>(merged.localpixels());
    if (!pixels || spec.format != TypeDesc::FLOAT) {
        error = "validate_inputs: expects a local float buffer (use read_inputs)";
        return false;
    }
    // Half files whose channels read_inputs did not read it checked from their headers.
    if (!check_color_faces(spec, aovs, spec.get_int_attribute(kHalvesUnread) != 1, error))
        return false;
    auto is_variance = [](Role r) {
        return r == Role::ColorVariance || r == Role::AlbedoVariance || r == Role::NormalVariance
               || r == Role::DepthVariance || r == Role::VisibilityVariance;
    };
    auto nan_allowed = [&](Role r) { return is_variance(r) && r != Role::ColorVariance; };
    auto problem_of = [&](Role role, float v) -> const char* {
        if (std::isnan(v) && !nan_allowed(role))
            return "NaN";
        if (std::isinf(v))
            return "Inf";
        if (std::fabs(v) > kHugeValue)
            return "a huge value (|v| > 1e15)";
        if (is_variance(role) && v < 0.0f)
            return "a negative variance";
        return nullptr;
    };
    const size_t npixels = spec.image_pixels();
    // One pass over the pixels finds whether anything is wrong (a pass per channel would
    // read the whole frame once per role channel); only then the channel-by-channel scan
    // below names the first problem.
    std::vector<std::pair<Role, int>> checked;
    // Motion vectors are not checked: only the cross-frame modes read them, and those take a
    // non-finite vector as no motion (ops/motion.h).
    for (int r = 0; r < kRoleCount; ++r)
        if (Role(r) != Role::Motion)
            for (int c : aovs.channels(Role(r)))
                checked.emplace_back(Role(r), c);
    bool clean = true;
    for (size_t p = 0; p < npixels && clean; ++p)
        for (const auto& [role, c] : checked)
            if (problem_of(role, pixels[p * nch + c])) {
                clean = false;
                break;
            }
    // Normals: their length (a sum over three channels), in the same pass's order.
    const std::vector<int>& normal = aovs.channels(Role::Normal);
    for (size_t p = 0; p < npixels && clean && normal.size() == 3; ++p) {
        const float* px = pixels + p * nch;
        const float length = std::sqrt(px[normal[0]] * px[normal[0]] + px[normal[1]] * px[normal[1]]
                                       + px[normal[2]] * px[normal[2]]);
        if (length > kMaxNormalLength) {
            int x = spec.x + int(p % spec.width), y = spec.y + int(p / spec.width);
            error = format("{}: channel '{}' (role normal) has a normal of length {:.3g} at "
                           "pixel ({}, {}), not a direction (at most {}): give unit normals, "
                           "or drop the pass",
                           channel_source(spec, spec.channelnames[normal[0]]),
                           spec.channelnames[normal[0]], length, x, y, kMaxNormalLength);
            return false;
        }
    }
    if (clean)
        return true;
    for (int r = 0; r < kRoleCount; ++r) {
        Role role = Role(r);
        if (role == Role::Motion)
            continue;
        for (int c : aovs.channels(role)) {
            for (size_t p = 0; p < npixels; ++p) {
                const char* problem = problem_of(role, pixels[p * nch + c]);
                if (!problem)
                    continue;
                int x = spec.x + int(p % spec.width), y = spec.y + int(p / spec.width);
                error = format("{}: channel '{}' (role {}) has {} at pixel ({}, {}): "
                               "fix the render, drop the pass, or repair it as it is read "
                               "(mcdntool -i FILE --fixnan box3 ...)",
                               channel_source(spec, spec.channelnames[c]), spec.channelnames[c],
                               role_name(role), problem, x, y);
                return false;
            }
        }
    }
    return true;
}

}  // namespace mcdn
