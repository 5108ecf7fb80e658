// The preparation step every mcdn op starts with (like ImageBufAlgo's IBAprep):
// resolve the AOV set against src and make dst a float copy of src (chaining keeps every
// channel); errors go on dst.
#pragma once

#include "mcdn/aov.h"

namespace mcdn {

/// dst's pixels for `spec`, zero-filled or not, with transparent huge pages asked for
/// before the first write (a fresh frame otherwise costs a page fault per 4 KB written).
/// False, with an error on dst saying the size, when memory runs out.
bool allocate_frame(ImageBuf& dst, const ImageSpec& spec, bool zero);

/// The checks of prepare_op without the copy (for ops that read src in bands): on failure
/// `error` names `op`.
bool check_op_input(const ImageBuf& src, const AovSpec& spec, AovSet& aovs, const char* op,
                    std::string& error);

/// On failure sets an error on dst naming `op` and returns false. The copy runs on
/// `nthreads` threads (0 = all cores): touching a fresh frame is page clearing, which
/// parallelises.
bool prepare_op(ImageBuf& dst, const ImageBuf& src, const AovSpec& spec, AovSet& aovs,
                const char* op, int nthreads = 1);

/// dst as a denoiser of the colour writes it, `aovs` resolved on src and holding the
/// colour: a copy of src (prepare_op), or for a SURE probe's colour-only result
/// (core/attributes.h kColourOnlyAttribute) its colour channels alone. Errors on dst.
bool prepare_denoiser_output(ImageBuf& dst, const ImageBuf& src, const AovSpec& spec, AovSet& aovs,
                             const char* op, bool color_only, int nthreads);

/// mcdn::check_threads for an op: on failure an error on dst naming `op`.
bool check_op_threads(ImageBuf& dst, int nthreads, const char* op);

/// The ROI an op writes: `roi` clipped to src's data window (all of it when undefined).
ROI output_roi(const ImageBuf& src, ROI roi);

}  // namespace mcdn
