// Adding named output channels to an op's result.
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

namespace mcdn {

/// Makes sure `buf` (a float buffer) has every channel in `names`, appending the missing
/// ones filled with zero, and returns their indices in `names` order. They join the
/// channels -o writes by default (kOutputChannelsAttribute, when buf has the list): a stage
/// adds channels only when asked to (nfor's mse=1, mix's alpha=1).
std::vector<int> add_channels(OIIO::ImageBuf& buf, const std::vector<std::string>& names);

/// A float copy of rows `rows` of src (every channel; all rows when undefined) with each of
/// `names` that src lacks appended, zero: an op that will add channels gets its copy with
/// room for them (one frame-sized copy, not two). The rows are copied on `nthreads`
/// threads (0 = all cores). kOutputChannelsAttribute is left as it is.
OIIO::ImageBuf copy_with_channels(const OIIO::ImageBuf& src, const std::vector<std::string>& names,
                                  OIIO::ROI rows = {}, int nthreads = 1);

}  // namespace mcdn
