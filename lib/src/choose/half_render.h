// One half buffer of a render as a render of its own: what choose's two-buffer estimate
// (mcdn/choose.h) runs each denoiser on.
#pragma once

#include <string>
#include <utility>
#include <vector>

#include <OpenImageIO/imagebuf.h>

#include "core/frame_facts.h"
#include "mcdn/aov.h"

namespace mcdn {

/// dst = half `face` (Face::HalfA or HalfB) of the render src holds, as a render without
/// halves: the colour and each other channel of a role or an extra AOV that has a half
/// buffer (the colour's by its role, the others' "A.<name>" or "B.<name>", aov.h's naming)
/// take that half's values and their variance ("variance.<name>") is doubled, since a half
/// is the mean of half the samples; channels of no role stay as they are (a chain reads no
/// half of them); the halves and what --sure added (noisy.*, sure.*) are left out, and so
/// is the list of input files (no half was given to dst). Other channels and attributes are src's,
/// so a denoiser reads dst as it would a render that came without halves (NFOR: its one-buffer
/// path). False with `error` where src has no halves of the colour.
bool half_render(OIIO::ImageBuf& dst, const OIIO::ImageBuf& src, const AovSet& aovs, Face face,
                 int nthreads, std::string& error);

/// What half_render makes of a render of spec `in`: dst's spec, and for each of its channels
/// the channel of src it comes from with its factor (2 for a variance). False with `error`
/// where `in` has no halves of the colour.
struct HalfLayout {
    ImageSpec spec;
    std::vector<std::pair<int, float>> taken;
};
bool half_layout(HalfLayout& layout, const ImageSpec& in, const AovSet& aovs, Face face,
                 std::string& error);

/// The facts (core/frame_facts.h) of the render src holds, which its half renders carry so
/// that the denoisers on them read the same numbers whether the frame runs whole or in a
/// chain's bands: a band's own (its frame's); else computed from src as the chain's light
/// pass computes them (chain/chain_bands.cpp) on the render: the sums of its colour
/// (`render`: noisy.*, as --sure recorded it) and variance, its autoexposure, the depth's
/// range, and which features and extras hold one value.
FrameFacts render_facts(const OIIO::ImageBuf& src, const AovSet& aovs, const int render[3]);

}  // namespace mcdn
