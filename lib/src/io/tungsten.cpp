// Tungsten's buffer folders (color.pfm, colorA.pfm, colorVariance.pfm, ...) in the generic
// layout of a merged buffer (mcdn/io.h read_tungsten_directory).
#include "mcdn/io.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>

#include "io/io_steps.h"

namespace mcdn {

using OIIO::TypeDesc;
namespace Filesystem = OIIO::Filesystem;
using OIIO::Strutil::fmt::format;

bool read_tungsten_directory(ImageBuf& dst, const std::string& dir)
{
    // buffer file stem -> channel names in the generic layout
    struct Buffer {
        const char* stem;
        std::vector<std::string> channels;
    };
    const Buffer buffers[] = {
        { "color", { "R", "G", "B" } },        { "albedo", { "albedo.R", "albedo.G", "albedo.B" } },
        { "normal", { "N.X", "N.Y", "N.Z" } }, { "depth", { "Z" } },
        { "visibility", { "visibility" } },
    };
    const std::pair<const char*, InputKind> faces[] = {
        { "", InputKind::Mean },
        { "Variance", InputKind::Variance },
        { "A", InputKind::HalfA },
        { "B", InputKind::HalfB },
    };

    std::vector<ImageBuf> pieces;
    std::vector<std::string> names;
    for (const auto& buffer : buffers) {
        for (const auto& [suffix, kind] : faces) {
            std::string file = format("{}/{}{}.pfm", dir, buffer.stem, suffix);
            if (!Filesystem::exists(file)) {
                if (std::string(buffer.stem) == "color" && kind == InputKind::Mean) {
                    dst.errorfmt("{}: not a Tungsten buffer directory (no color.pfm)", dir);
                    return false;
                }
                continue;
            }
            ImageBuf piece;
            if (!read_image(piece, file)) {
                dst.errorfmt("{}", piece.geterror());
                return false;
            }
            int n = int(buffer.channels.size());
            if (piece.nchannels() < n) {
                dst.errorfmt("{}: has {} channel(s), {} needs {}", file, piece.nchannels(),
                             buffer.stem, n);
                return false;
            }
            if (!pieces.empty() && !same_window(piece.roi(), pieces[0].roi())) {
                dst.errorfmt("{}: size {} differs from color.pfm's {}", file, roi_text(piece.roi()),
                             roi_text(pieces[0].roi()));
                return false;
            }
            pieces.push_back(OIIO::ImageBufAlgo::channels(piece, n, {}));
            for (const auto& ch : buffer.channels)
                names.push_back(input_kind_prefix(kind) + ch);
        }
    }
    ImageSpec spec(pieces[0].roi(), TypeDesc::FLOAT);
    spec.nchannels = int(names.size());
    spec.channelnames = names;
    spec.alpha_channel = spec.z_channel = -1;
    ImageBuf out(spec);
    int first = 0;
    for (const auto& piece : pieces) {
        copy_channels(out, first, piece);
        first += piece.nchannels();
    }
    dst = std::move(out);
    return true;
}

}  // namespace mcdn
