// libFuzzer target: mcdntool's command line (one argument a line) through the parser and the
// checks of every command's modifiers, then the frame patterns and --frames ranges. Nothing
// runs and no file is read (ArgParse's `role=chans` rule only asks whether a path exists).
#include "command_line.h"
#include "fuzz_common.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    std::vector<std::string> words = mcdn_fuzz::lines_of(data, size);
    std::vector<const char*> argv = { "mcdntool" };
    for (const auto& w : words)
        argv.push_back(w.c_str());
    int argc = int(argv.size());
    argv.push_back(nullptr);
    if (mcdntool::wants_help(argc, argv.data()))
        return 0;  // prints the help and exits in main: nothing to parse

    mcdntool::CommandLine line;
    std::string error;
    if (!mcdntool::parse_command_line(argc, argv.data(), line, error))
        return 0;
    std::vector<int> frames;
    if (!line.frames.empty())
        mcdntool::frames_from_spec(line.frames, frames, error);
    for (const auto& command : line.commands)
        for (const auto& arg : command.args) {
            std::string normalized, framespec;
            if (!mcdntool::is_sequence(arg, normalized, framespec))
                continue;
            mcdntool::frame_name(normalized, frames.empty() ? 1 : frames.back());
            if (!framespec.empty())
                mcdntool::frames_from_spec(framespec, frames, error);
        }
    return 0;
}
