// mcdntool's command line: commands in oiiotool's grammar (`--name:mod=value:mod2=v ARGS`),
// the table that declares them, and the checks that turn a typo into a suggestion.
#pragma once

#include <functional>
#include <map>
#include <string>
#include <vector>

namespace mcdntool {

/// One command as typed, e.g. `--metrics:format=json:trim=1 ref.exr`.
struct Command {
    std::string name;                              // "--metrics"
    std::map<std::string, std::string> modifiers;  // {"format": "json", "trim": "1"}
    std::vector<std::string> args;                 // {"ref.exr"}

    std::string modifier(const std::string& key, const std::string& fallback = "") const;
    bool has(const std::string& key) const { return modifiers.count(key) != 0; }
    /// A numeric modifier: `value` is left alone when absent; false with `error` when it is
    /// not a finite number.
    bool number(const std::string& key, double& value, std::string& error) const;
};

class Session;

/// What a command does to the session of one frame; false with `error` set on failure.
using CommandAction = std::function<bool(Session&, const Command&, std::string& error)>;
/// Checks a command's modifier values and arguments before anything runs (no file is read):
/// false with `error` set when a value can never work (--sure:seed=abc).
using CommandCheck = std::function<bool(const Command&, std::string& error)>;

struct CommandInfo {
    std::string name;                    // "--metrics"
    std::string metavar;                 // "REF" (space-separated, one per argument)
    std::vector<std::string> modifiers;  // accepted modifier keys
    std::string help;
    CommandAction run;    // null for commands handled before the frame loop
    bool global = false;  // --threads, --frames: set once, not per frame
    CommandCheck check;   // null when any value is accepted
    std::string needs;    // what it reads, for --help COMMAND (stages)
};

/// Every command mcdntool knows, in --help order (built-ins, then the stages).
const std::vector<CommandInfo>& command_table();
const CommandInfo* find_command(const std::string& name);

/// Splits `--name:a=1:b=2` into name and modifiers; a bare `:flag` means flag=1.
Command split_command(const std::string& typed);

/// Checks a command name and its modifiers against the table. On failure `error` says
/// what is wrong and suggests the closest known name.
bool check_command(const Command& command, std::string& error);

/// The closest of `candidates` to `word` (edit distance), or "" if none is close.
std::string closest(const std::string& word, const std::vector<std::string>& candidates);

}  // namespace mcdntool
