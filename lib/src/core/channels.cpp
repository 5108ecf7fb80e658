#include "core/channels.h"

#include <OpenImageIO/imagebufalgo.h>

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
    if (all.size() != spec.channelnames.size()) {
        OIIO::ImageBuf grown;
        OIIO::ImageBufAlgo::channels(grown, buf, int(all.size()), order, fill, all);
        buf = std::move(grown);
    }
    std::vector<int> indices;
    for (const auto& name : names)
        indices.push_back(buf.spec().channelindex(name));
    return indices;
}

}  // namespace mcdn
