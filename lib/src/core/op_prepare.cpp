#include "core/op_prepare.h"

#include <algorithm>
#include <cstring>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/channels.h"
#include "core/huge_pages.h"
#include "core/planar.h"
#include "mcdn/threads.h"

namespace mcdn {

bool allocate_frame(ImageBuf& dst, const ImageSpec& spec, bool zero)
{
    dst.reset(spec, OIIO::InitializePixels::No);
    if (!dst.localpixels()) {
        // OIIO leaves a buffer without pixels and its own message: ours says the frame.
        dst.geterror();
        dst.errorfmt("out of memory for a {}x{} frame of {} channels ({:.2f} GB)", spec.width,
                     spec.height, spec.nchannels, double(spec.image_bytes()) / 1e9);
        return false;
    }
    advise_huge_pages(dst.localpixels(), dst.spec().image_bytes());
    if (zero)
        std::memset(dst.localpixels(), 0, dst.spec().image_bytes());
    return true;
}

bool check_op_threads(ImageBuf& dst, int nthreads, const char* op)
{
    std::string error;
    if (check_threads(nthreads, error))
        return true;
    dst.errorfmt("{}: {}", op, error);
    return false;
}

bool check_op_input(const ImageBuf& src, const AovSpec& spec, AovSet& aovs, const char* op,
                    std::string& error)
{
    if (!src.initialized()) {
        error = OIIO::Strutil::fmt::format("{}: the input image is empty (nothing was read)", op);
        return false;
    }
    if (src.spec().depth > 1) {
        error = OIIO::Strutil::fmt::format("{}: volume images are not supported", op);
        return false;
    }
    std::string why;
    if (!resolve_aovs(aovs, spec, src.spec(), why)) {
        error = OIIO::Strutil::fmt::format("{}: {}", op, why);
        return false;
    }
    return true;
}

bool prepare_op(ImageBuf& dst, const ImageBuf& src, const AovSpec& spec, AovSet& aovs,
                const char* op, int nthreads)
{
    std::string error;
    if (!check_op_input(src, spec, aovs, op, error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    if (&dst == &src)
        return true;
    // Room for channels a caller will add (core/attributes.h): the copy made with them.
    const std::string room = src.spec().get_string_attribute(kOutputRoomAttribute);
    if (!room.empty()) {
        dst = copy_with_channels(src, OIIO::Strutil::splits(room, "\n"), {}, nthreads);
        if (!dst.localpixels()) {
            dst.errorfmt("{}: out of memory for a copy of the input with {} more channels", op,
                         OIIO::Strutil::splits(room, "\n").size());
            return false;
        }
        dst.specmod().erase_attribute(kOutputRoomAttribute);
        return true;
    }
    // Fast path: a float buffer in memory is copied with one memcpy (ImageBuf::copy goes
    // pixel by pixel, slow on many-channel frames).
    if (const float* pixels = float_frame_pixels(src)) {
        // Not zero-filled: zeroing would fault every 4 KB page before the advice.
        if (!allocate_frame(dst, src.spec(), false)) {
            std::string why = dst.geterror();
            dst.errorfmt("{}: {}", op, why);
            return false;
        }
        // In 2 MB pieces (a huge page each), as many at once as there are threads.
        constexpr size_t kPiece = size_t(2) << 20;
        const size_t bytes = src.spec().image_bytes();
        char* to = static_cast<char*>(dst.localpixels());
        const char* from = reinterpret_cast<const char*>(pixels);
        parallel_for_index(int((bytes + kPiece - 1) / kPiece), nthreads, [&](int i) {
            const size_t begin = size_t(i) * kPiece;
            std::memcpy(to + begin, from + begin, std::min(kPiece, bytes - begin));
        });
        return true;
    }
    if (!dst.copy(src, OIIO::TypeDesc::FLOAT)) {
        std::string why = dst.geterror();
        dst.errorfmt("{}: could not copy the input: {}", op, why);
        return false;
    }
    return true;
}

ROI output_roi(const ImageBuf& src, ROI roi)
{
    ROI all = OIIO::get_roi(src.spec());
    return roi.defined() ? OIIO::roi_intersection(roi, all) : all;
}

bool prepare_denoiser_output(ImageBuf& dst, const ImageBuf& src, const AovSpec& spec, AovSet& aovs,
                             const char* op, bool color_only, int nthreads)
{
    std::string error;
    if (color_only) {
        if (!check_op_input(src, spec, aovs, op, error)
            || !aovs.require({ Role::Color }, src.spec(), error)) {
            dst.errorfmt("{}", error);
            return false;
        }
        const std::vector<int>& c = aovs.channels(Role::Color);
        dst = OIIO::ImageBufAlgo::channels(src, 3, c, {},
                                           { src.spec().channel_name(c[0]),
                                             src.spec().channel_name(c[1]),
                                             src.spec().channel_name(c[2]) });
        if (dst.has_error() || !dst.localpixels()) {
            dst.errorfmt("{}: could not make the probe's colour frame", op);
            return false;
        }
    } else if (!prepare_op(dst, src, spec, aovs, op, nthreads)) {
        return false;
    }
    if (!aovs.require({ Role::Color }, src.spec(), error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    return true;
}

}  // namespace mcdn
