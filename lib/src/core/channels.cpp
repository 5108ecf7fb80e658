#include "core/channels.h"

#include <algorithm>
#include <cstring>

#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/op_prepare.h"
#include "core/planar.h"
#include "mcdn/threads.h"

namespace mcdn {

OIIO::ImageBuf copy_with_channels(const OIIO::ImageBuf& src, const std::vector<std::string>& names,
                                  OIIO::ROI rows, int nthreads)
{
    const OIIO::ROI whole = src.roi();
    if (!rows.defined())
        rows = whole;
    OIIO::ImageSpec spec = src.spec();
    spec.set_format(OIIO::TypeDesc::FLOAT);
    spec.channelformats.clear();
    spec.y = rows.ybegin;
    spec.height = rows.height();
    const int old_channels = spec.nchannels;
    for (const auto& name : names)
        if (spec.channelindex(name) < 0) {
            spec.channelnames.push_back(name);
            ++spec.nchannels;
        }
    OIIO::ImageBuf dst;
    if (!allocate_frame(dst, spec, false)) {
        dst.geterror();  // the callers say it (no pixels), naming their step
        return dst;
    }
    const int nch = spec.nchannels;
    // Row by row straight into dst's pixels with its strides, the new channels zeroed there.
    parallel_for_index(rows.height(), nthreads, [&](int r) {
        const int y = rows.ybegin + r;
        OIIO::ROI row(whole.xbegin, whole.xend, y, y + 1, 0, 1, 0, old_channels);
        float* to = static_cast<float*>(dst.pixeladdr(whole.xbegin, y));
        src.get_pixels(row, OIIO::TypeDesc::FLOAT, to, dst.pixel_stride(), dst.scanline_stride());
        if (nch > old_channels)
            for (int x = 0; x < whole.width(); ++x)
                std::fill(to + size_t(x) * nch + old_channels, to + size_t(x + 1) * nch, 0.0f);
    });
    return dst;
}

std::vector<int> add_channels(OIIO::ImageBuf& buf, const std::vector<std::string>& names)
{
    if (std::any_of(names.begin(), names.end(),
                    [&](const std::string& name) { return buf.spec().channelindex(name) < 0; }))
        buf = copy_with_channels(buf, names);
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
