// The frames of a command line (frames.h): which frames it runs on, each frame's commands,
// the files a frame reads and writes checked before anything runs.
#include "frames.h"

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/strutil.h>

#include "command_line.h"
#include "session.h"

namespace mcdntool {

using OIIO::Strutil::fmt::format;
namespace Filesystem = OIIO::Filesystem;
namespace Strutil = OIIO::Strutil;

// The frames a command line runs on: --frames, a range written in a pattern
// (shot.1-10#.exr), or every frame of the first input pattern found on disk.
bool find_frames(const std::vector<Command>& commands, const std::string& frames_option,
                 std::vector<int>& frames, std::string& error)
{
    std::string first_input_pattern, pattern_range;
    bool any_sequence = false;
    for (const auto& c : commands)
        for (const auto& arg : c.args) {
            std::string normalized, framespec;
            if (frame_patterns(arg) > 1) {
                error = format("{} {}: {} frame patterns in one name; a name takes one (#, @ "
                               "or %04d), e.g. out.#.exr",
                               c.name, arg, frame_patterns(arg));
                return false;
            }
            if (!is_sequence(arg, normalized, framespec)) {
                // Blender's and Nuke's padding (#### for 4 digits) is not oiiotool's, where
                // each # is 4 digits: such a name would be taken literally, then not found.
                if ((c.name == "-i" || c.name == "-o") && arg.find("##") != std::string::npos
                    && !Filesystem::exists(arg)) {
                    error = format("{} {}: '#' stands for 4 digits here, as in oiiotool "
                                   "(and '@' for one), so this name asks for {} digits: "
                                   "Blender's and Nuke's shot.####.exr is shot.#.exr (or "
                                   "shot.%04d.exr) here",
                                   c.name, arg, 4 * std::count(arg.begin(), arg.end(), '#'));
                    return false;
                }
                continue;
            }
            any_sequence = true;
            if (pattern_range.empty())
                pattern_range = framespec;
            if (c.name == "-i" && first_input_pattern.empty())
                first_input_pattern = normalized;
        }
    // A sequence written to one file would overwrite it every frame.
    const bool input_sequence = !first_input_pattern.empty();
    for (const auto& c : commands) {
        std::string normalized, framespec;
        if (input_sequence && (c.name == "-o" || c.name == "--heatmap")
            && !is_sequence(c.args[0], normalized, framespec)) {
            error = format("{} {}: the inputs are a frame sequence but this name has no frame "
                           "pattern, so every frame would overwrite it (write e.g. "
                           "out.#.exr)",
                           c.name, c.args[0]);
            return false;
        }
    }
    if (!any_sequence) {
        if (!frames_option.empty()) {
            error = "--frames given but no file name has a frame pattern (#, @ or %04d)";
            return false;
        }
        return true;
    }
    std::string spec = !frames_option.empty() ? frames_option : pattern_range;
    if (!spec.empty())
        return frames_from_spec(spec, frames, error);
    std::vector<std::string> files;
    if (first_input_pattern.empty()
        || !Filesystem::scan_for_matching_filenames(first_input_pattern, frames, files)
        || frames.empty()) {
        error = format("no frames found for '{}': give --frames",
                       first_input_pattern.empty() ? "the output pattern" : first_input_pattern);
        return false;
    }
    // shot.1.exr and shot.0001.exr both match shot.@.exr: the same frame twice.
    for (size_t i = 0; i < frames.size(); ++i)
        for (size_t j = i + 1; j < frames.size(); ++j)
            if (frames[i] == frames[j]) {
                error = format("{} and {} are both frame {} of '{}': padded differently; "
                               "give the padding (# is 4 digits, @ one) or --frames",
                               files[i], files[j], frames[i], first_input_pattern);
                return false;
            }
    return true;
}

// Every file a frame writes (-o, --heatmap) may be written, and is none of the files it
// reads (-i, --metrics, --heatmap:ref): checked before the first stage runs.
bool check_outputs(const std::vector<Command>& commands, std::string& error)
{
    std::vector<std::string> reads;
    for (const auto& c : commands) {
        if (c.name == "-i" || c.name == "--metrics")
            reads.push_back(c.args[0]);
        if (c.name == "--heatmap" && c.has("ref"))
            reads.push_back(c.modifier("ref"));
    }
    for (const auto& c : commands)
        if ((c.name == "-o" || c.name == "--heatmap")
            && !mcdn::check_output_path(c.args[0], reads, error))
            return false;
    return true;
}

// The command line of one frame (frame < 0: no sequence): patterns replaced by its names.
std::vector<Command> frame_commands(std::vector<Command> commands, int frame)
{
    if (frame >= 0)
        for (Command& c : commands)
            for (auto& arg : c.args) {
                std::string normalized, framespec;
                if (is_sequence(arg, normalized, framespec))
                    arg = frame_name(normalized, frame);
            }
    return commands;
}

// Every file the frame reads (-i, --metrics, --heatmap:ref) is a regular file (or, for -i,
// a Tungsten buffer folder): a FIFO or a device would hang the first header read (OIIO
// probes a file by reading it), before anything could say so.
bool check_inputs(const std::vector<Command>& commands, std::string& error)
{
    for (const auto& c : commands) {
        std::string path;
        if ((c.name == "-i" && !Filesystem::is_directory(c.args[0])) || c.name == "--metrics")
            path = c.args[0];
        else if (c.name == "--heatmap" && c.has("ref"))
            path = c.modifier("ref");
        if (!path.empty() && !mcdn::check_input_file(path, error))
            return false;
    }
    return true;
}

// True when the frame writes something and all of it exists (--skip-existing).
bool outputs_exist(const std::vector<Command>& commands)
{
    bool any = false;
    for (const auto& c : commands)
        if (c.name == "-o" || c.name == "--heatmap") {
            if (!Filesystem::exists(c.args[0]))
                return false;
            any = true;
        }
    return any;
}

// The inputs of frame `frame` of the shot (the -i commands of `commands`, patterns
// replaced), false when a file is missing: a cross-frame stage's neighbours (--nfor:frames).
bool shot_frame_inputs(const std::vector<Command>& commands, int frame,
                       std::vector<mcdn::InputFile>& inputs)
{
    if (frame < 0)
        return false;
    for (const Command& c : frame_commands(commands, frame))
        if (c.name == "-i") {
            mcdn::InputFile file;
            std::string error;
            if (!input_file_of(c, file, error) || !Filesystem::exists(file.path))
                return false;
            add_input(inputs, file);
        }
    return !inputs.empty();
}

}  // namespace mcdntool
