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

}  // namespace mcdn
