// Adding named output channels to an op's result.
#pragma once

#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

namespace mcdn {

/// Makes sure `buf` (a float buffer) has every channel in `names`, appending the missing
/// ones filled with zero, and returns their indices in `names` order.
std::vector<int> add_channels(OIIO::ImageBuf& buf, const std::vector<std::string>& names);

}  // namespace mcdn
