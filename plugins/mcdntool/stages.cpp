// The denoising stages as mcdntool commands: each maps its modifiers onto the stage's
// Options and runs the library op on the current image.
#include "session.h"

namespace mcdntool {

std::vector<CommandInfo> stage_commands()
{
    return {};
}

}  // namespace mcdntool
