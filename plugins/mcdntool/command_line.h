// The whole mcdntool command line parsed into commands, before any of them runs: no file is
// read and no denoiser runs, so a typo at the end of a long line fails at once.
#pragma once

#include <string>
#include <vector>

#include "command.h"

namespace mcdntool {

struct CommandLine {
    std::vector<Command> commands;  // every command in order (the global ones run nothing)
    int nthreads = 0;               // --threads
    bool verbose = false;           // -v
    std::string frames;             // --frames SPEC
    int parallel_frames = 1;        // --parallel-frames
    bool skip_existing = false;     // --skip-existing
    bool skip_bad_frames = false;   // --skip-bad-frames, --continue
    std::string text;               // "mcdntool ARGS", as typed (Exif:ImageHistory)
};

/// True when the command line has --version ("mcdntool X.Y.Z" on stdout, exit 0).
bool wants_version(int argc, const char** argv);
/// True when the user asked for --help (or gave no arguments); `command` is the command
/// named after it (`--help nfor`, `--help --nfor`), else empty.
bool wants_help(int argc, const char** argv, std::string* command = nullptr);
void print_help();
/// One command's help: what it does, what it reads, its modifiers. False when there is no
/// such command (with a suggestion on stderr).
bool print_command_help(const std::string& name);

/// Parses argv (argv[0] is the program) into `line`: command names, modifier keys, argument
/// counts and modifier values are checked, with suggestions for typos. `line.verbose` keeps
/// the caller's default unless -v is given.
bool parse_command_line(int argc, const char** argv, CommandLine& line, std::string& error);

/// A file name with frame numbers in it: '#', '@' or printf's %d. `normalized` is the name
/// with the frame number as one printf conversion, `framespec` a range written in it
/// (shot.1-10#.exr). A name with any other '%' is taken literally.
bool is_sequence(const std::string& name, std::string& normalized, std::string& framespec);
/// The name of one frame of a normalized pattern.
std::string frame_name(const std::string& normalized, int frame);
/// How many frame patterns (runs of # or @, %d / %04d) `name` holds: a name takes one.
int frame_patterns(const std::string& name);

/// The frames a --frames or pattern range spec names (1-10, 1-100x5, 3,7,9); false with
/// `error` for a malformed spec or one naming more than `max_frames` frames.
bool frames_from_spec(const std::string& spec, std::vector<int>& frames, std::string& error,
                      size_t max_frames = 1000000);
/// The check of --frames SPEC.
bool check_frames(const Command& command, std::string& error);

}  // namespace mcdntool
