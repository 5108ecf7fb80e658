#include "core/channels.h"

#include <algorithm>
#include <cstring>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/planar.h"

namespace mcdn {

std::vector<int> add_channels(OIIO::ImageBuf& buf, const std::vector<std::string>& names)
{
    const OIIO::ImageSpec& spec = buf.spec();
    std::vector<int> order;
    std::vector<float> fill;
    std::vector<std::string> all = spec.channelnames;
    for (int c = 0; c < spec.nchannels; ++c) {
        order.push_back(c);
        fill.push_back(0.0f);
    }
    for (const auto& name : names)
        if (spec.channelindex(name) < 0) {
            order.push_back(-1);  // IBA::channels fills -1 entries with the fill value
            fill.push_back(0.0f);
            all.push_back(name);
        }
    if (all.size() != spec.channelnames.size() && float_frame_pixels(buf)) {
        // Fast path for a float buffer in memory: one memcpy per pixel (IBA::channels goes
        // value by value, slow on many-channel frames).
        OIIO::ImageSpec grown_spec = spec;
        grown_spec.nchannels = int(all.size());
        grown_spec.channelnames = all;
        grown_spec.channelformats.clear();
        OIIO::ImageBuf grown(grown_spec);
        const size_t pixels = spec.image_pixels(), old_bytes = spec.pixel_bytes();
        const size_t new_floats = all.size();
        const char* from = static_cast<const char*>(buf.localpixels());
        float* to = static_cast<float*>(grown.localpixels());
        for (size_t p = 0; p < pixels; ++p) {
            std::memcpy(to + p * new_floats, from + p * old_bytes, old_bytes);
            std::fill(to + p * new_floats + spec.nchannels, to + (p + 1) * new_floats, 0.0f);
        }
        buf = std::move(grown);
    } else if (all.size() != spec.channelnames.size()) {
        OIIO::ImageBuf grown;
        OIIO::ImageBufAlgo::channels(grown, buf, int(all.size()), order, fill, all);
        buf = std::move(grown);
    }
    // Asked for, so written: a merged render's list of the channels write_image writes by
    // default gains them.
    const std::string listed = buf.spec().get_string_attribute(kOutputChannelsAttribute);
    if (!listed.empty()) {
        std::vector<std::string> output = OIIO::Strutil::splits(listed, "\n");
        for (const auto& name : names)
            if (std::find(output.begin(), output.end(), name) == output.end())
                output.push_back(name);
        buf.specmod().attribute(kOutputChannelsAttribute, OIIO::Strutil::join(output, "\n"));
    }
    std::vector<int> indices;
    for (const auto& name : names)
        indices.push_back(buf.spec().channelindex(name));
    return indices;
}

}  // namespace mcdn
