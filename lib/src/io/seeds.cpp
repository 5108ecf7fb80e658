// K renders of one frame that differ only in their sampling seed (mcdn/io.h combine_seeds):
// K independent estimates of every pixel's integral. Their mean is the render at K times
// the samples; their spread is its noise: the sample variance over K is the variance of the
// mean (PD §2.3's per-pixel variance), and the means of the first and the last K/2 seeds
// are two independent half buffers of it (NFOR §5). What a renderer without a variance
// pass (Cycles 3.x) can still give the chains that need one.
#include "mcdn/io.h"

#include <OpenImageIO/imagebufalgo_util.h>
#include <OpenImageIO/strutil.h>

#include "core/op_prepare.h"
#include "io/io_steps.h"

namespace mcdn {

using OIIO::ROI;
using OIIO::TypeDesc;
using OIIO::Strutil::fmt::format;
namespace Strutil = OIIO::Strutil;

namespace {

bool is_identifier_channel(string_view name)
{
    // Object and material IDs are labels, not radiance: a mean of two seeds' IDs is no ID.
    return Strutil::icontains(name, "crypto") || Strutil::contains(name, "IndexOB")
           || Strutil::contains(name, "IndexMA");
}

}  // namespace

bool combine_seeds(ImageBuf& dst, const std::vector<std::string>& seeds)
{
    const int k = int(seeds.size());
    if (k < 2) {
        dst.errorfmt("{}: -i:as=seed needs two or more renders of the frame with different "
                     "seeds (one gives no variance)",
                     seeds.empty() ? std::string("-i:as=seed") : seeds[0]);
        return false;
    }
    std::vector<ImageBuf> renders(k);
    for (int s = 0; s < k; ++s) {
        if (!read_image(renders[s], seeds[s])) {
            dst.errorfmt("{}", renders[s].geterror());
            return false;
        }
        const ImageSpec& a = renders[0].spec();
        const ImageSpec& b = renders[s].spec();
        if (!same_window(a.roi(), b.roi())) {
            dst.errorfmt("{}: data window {} differs from the seed {}'s {}", seeds[s],
                         roi_text(b.roi()), seeds[0], roi_text(a.roi()));
            return false;
        }
        for (int c = 0; c < std::max(a.nchannels, b.nchannels); ++c) {
            const std::string here = c < b.nchannels ? b.channelnames[c] : "(none)";
            const std::string there = c < a.nchannels ? a.channelnames[c] : "(none)";
            if (here != there) {
                dst.errorfmt("{}: channel {} is '{}' where the seed {} has '{}': seeds are "
                             "renders of one frame with the same passes",
                             seeds[s], c, here, seeds[0], there);
                return false;
            }
        }
    }

    const ImageSpec& first = renders[0].spec();
    std::vector<int> averaged;  // the channels that get faces
    for (int c = 0; c < first.nchannels; ++c)
        if (!is_identifier_channel(first.channelnames[c]))
            averaged.push_back(c);
    const bool halves = k % 2 == 0;
    ImageSpec spec = first;
    std::vector<const char*> faces = { "variance." };
    if (halves)
        faces.insert(faces.end(), { "A.", "B." });
    for (const char* prefix : faces)
        for (int c : averaged)
            spec.channelnames.push_back(prefix + first.channelnames[c]);
    spec.nchannels = int(spec.channelnames.size());
    spec.attribute("mcdn:seeds", k);
    ImageBuf out;
    if (!allocate_frame(out, spec, false)) {
        dst.errorfmt("{}: {}", seeds[0], one_line(out.geterror()));
        return false;
    }

    const int n = first.nchannels, m = int(averaged.size());
    const int64_t row = int64_t(first.width) * n, out_row = int64_t(spec.width) * spec.nchannels;
    OIIO::ImageBufAlgo::parallel_image(first.roi(), 0, [&](ROI roi) {
        for (int y = roi.ybegin; y < roi.yend; ++y) {
            std::vector<const float*> in(k);
            for (int s = 0; s < k; ++s)
                in[s] = static_cast<const float*>(renders[s].localpixels()) + (y - first.y) * row;
            float* o = static_cast<float*>(out.localpixels()) + (y - first.y) * out_row;
            for (int x = 0; x < first.width; ++x, o += spec.nchannels) {
                const int64_t p = int64_t(x) * n;
                for (int c = 0; c < n; ++c)
                    o[c] = in[0][p + c];  // identifiers: the first seed's
                for (int j = 0; j < m; ++j) {
                    const int c = averaged[j];
                    double sum = 0, sum_a = 0;
                    for (int s = 0; s < k; ++s) {
                        sum += in[s][p + c];
                        if (s < k / 2)
                            sum_a += in[s][p + c];
                    }
                    const double mean = sum / k;
                    double squares = 0;
                    for (int s = 0; s < k; ++s)
                        squares += (in[s][p + c] - mean) * (in[s][p + c] - mean);
                    o[c] = float(mean);
                    o[n + j] = float(squares / (k - 1) / k);
                    if (halves) {
                        o[n + m + j] = float(sum_a / (k / 2));
                        o[n + 2 * m + j] = float((sum - sum_a) / (k / 2));
                    }
                }
            }
        }
    });
    dst = std::move(out);
    return true;
}

}  // namespace mcdn
