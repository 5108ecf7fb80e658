// Extra AOVs (light groups, Diff/Gloss layers) are denoised with the beauty's own weights:
// NFOR fits them with the beauty's regression weights and bandwidth choice, KPCN filters
// them with the beauty's kernels. Every step is then linear in the extra, so extras that add
// up to the beauty still do after denoising.
#pragma once

#include <string>
#include <vector>

#include "core/planar.h"
#include "mcdn/aov.h"

namespace mcdn {

/// One 3-channel extra AOV as planes (sanitized), and the channels its result goes to.
struct ExtraPlanes {
    std::string name;
    std::string partition;  // AovSet::Extra::partition
    std::vector<int> channels;
    Plane mean[3], half_a[3], half_b[3];
};

/// Whether an op denoises the extras of src: asked for, and src is not a SURE probe (whose
/// result only counts for the colour; sure.h).
bool denoises_extras(bool asked, const ImageBuf& src);

/// Whether the channels `names` of a buffer with `spec` hold light, factor × pass: an extra
/// with a factor (AovSet::Extra::factor) in a buffer mcdn::into_working_space converted.
bool extra_holds_light(const ImageSpec& spec, const AovSet& aovs,
                       const std::vector<std::string>& names);

/// Whether an extra's channels are also a role's (Arnold's `diffuse` is the CNN's split and
/// a light pass to denoise): an op that reads roles as it writes extras cannot then work in
/// place.
bool extras_are_roles(const AovSet& aovs);

/// Reads the extras of `aovs` from src; with `halves`, also their half buffers. An extra
/// without halves of its own takes its share of the beauty's: E_A = E + (C_A − C)·E/C (and
/// E where C is ~0), so a set of extras that partitions the beauty has halves that partition
/// the beauty's halves. An extra that holds 0 over the frame in its mean and halves (an
/// empty light group) is left out: it stays as rendered, which is what denoising it would
/// give, and the others still add up to the beauty. False (with `error` naming the AOV) for
/// an extra that is not RGB.
bool read_extras(std::vector<ExtraPlanes>& extras, const ImageBuf& src, const AovSet& aovs,
                 bool halves, std::string& error);

}  // namespace mcdn
