#include "core/op_prepare.h"

#include <cstring>

namespace mcdn {

bool prepare_op(ImageBuf& dst, const ImageBuf& src, const AovSpec& spec, AovSet& aovs,
                const char* op)
{
    if (!src.initialized()) {
        dst.errorfmt("{}: the input image is empty (nothing was read)", op);
        return false;
    }
    if (src.spec().depth > 1) {
        dst.errorfmt("{}: volume images are not supported", op);
        return false;
    }
    std::string error;
    if (!resolve_aovs(aovs, spec, src.spec(), error)) {
        dst.errorfmt("{}: {}", op, error);
        return false;
    }
    if (&dst == &src)
        return true;
    // Fast path: a float buffer in memory is copied with one memcpy (ImageBuf::copy goes
    // pixel by pixel, ~0.15 s for 156 channels at 256×256).
    if (src.localpixels() && src.spec().format == OIIO::TypeDesc::FLOAT
        && src.pixel_stride() == OIIO::stride_t(src.spec().pixel_bytes())
        && src.scanline_stride() == OIIO::stride_t(src.spec().scanline_bytes())) {
        dst.reset(src.spec());
        std::memcpy(dst.localpixels(), src.localpixels(), src.spec().image_bytes());
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

}  // namespace mcdn
