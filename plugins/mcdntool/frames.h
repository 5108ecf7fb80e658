// The frames of a command line (frames.cpp): which frames it runs on, each frame's commands,
// the files a frame reads and writes checked before anything runs.
#pragma once

#include <string>
#include <vector>

#include "mcdn/io.h"

#include "command.h"

namespace mcdntool {

/// The frames a command line runs on: --frames, a range written in a pattern
/// (shot.1-10#.exr), or every frame of the first input pattern found on disk; empty when it
/// names no sequence.
bool find_frames(const std::vector<Command>& commands, const std::string& frames_option,
                 std::vector<int>& frames, std::string& error);

/// The command line of one frame (frame < 0: no sequence): patterns replaced by its names.
std::vector<Command> frame_commands(std::vector<Command> commands, int frame);

/// Every file a frame writes (-o, --heatmap) may be written, and is none of the files it
/// reads (-i, --metrics, --heatmap:ref).
bool check_outputs(const std::vector<Command>& commands, std::string& error);

/// Every file the frame reads is a regular file (or, for -i, a Tungsten buffer folder): a
/// FIFO or a device would hang the first header read.
bool check_inputs(const std::vector<Command>& commands, std::string& error);

/// True when the frame writes something and all of it exists (--skip-existing).
bool outputs_exist(const std::vector<Command>& commands);

/// The inputs of frame `frame` of the shot (the -i commands, patterns replaced); false when
/// a file is missing: a cross-frame stage's neighbours (--nfor:frames).
bool shot_frame_inputs(const std::vector<Command>& commands, int frame,
                       std::vector<mcdn::InputFile>& inputs);

}  // namespace mcdntool
