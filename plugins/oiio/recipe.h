// The recipe of the mcdn format plugin: `shot.mcdn?in=beauty.exr&chain=denoise` or a
// recipe file with the same keys, parsed into what to read and which chain to run. Nothing
// here reads an image or runs a stage (the fuzz target in tests/fuzz drives it).
#pragma once

#include <istream>
#include <map>
#include <string>
#include <vector>

#include "mcdn/chain.h"
#include "mcdn/io.h"

namespace mcdn_plugin {

/// key -> value, as written.
using Recipe = std::map<std::string, std::string>;

/// `%41` -> `A`; a '%' not followed by two hex digits stays as it is.
std::string url_decode(const std::string& text);

/// `key = value` lines of a recipe file (`#` at a line's start or after white space starts a
/// comment, so `shot#1.exr` is a path; a UTF-8 BOM is skipped). `file` names it in errors;
/// relative paths of in/variance/halfA/halfB become relative to its folder.
bool parse_recipe_lines(std::istream& in, const std::string& file, Recipe& recipe,
                        std::string& error);

/// `k=v&k2=v2` (URL-encoded; %00 is an error), on top of what `recipe` holds.
bool parse_query(const std::string& query, Recipe& recipe, std::string& error);

/// `name` is "file.mcdn", "file.mcdn?k=v&k2=v2" or "?k=v": the file's lines first (when
/// the file exists), the query on top.
bool parse_recipe(const std::string& name, Recipe& recipe, std::string& error);

/// What a recipe asks for.
struct Job {
    std::vector<mcdn::InputFile> inputs;  // the render first, then variance, halves
    mcdn::ChainOptions chain;
    std::vector<std::string> channels;  // output channels; empty = the render's own
    int threads = 0;
};

/// Checks the keys (unknown ones are errors, `stage.setting` keys go to the chain), the
/// chain's stage names and threads=; false with `error` when the recipe cannot run.
bool job_from_recipe(const Recipe& recipe, Job& job, std::string& error);

/// One name per recipe however it is spelt (./a.mcdn, a.mcdn, /abs/a.mcdn; the query kept).
std::string recipe_key(const std::string& name);

/// What a recipe's result depends on, as it is on disk now: the recipe file's and each of
/// its input files' inode, size and modification time (a nested recipe's own, recursively).
/// A result cached under recipe_key() + recipe_stamp() is one of the files as they are.
std::string recipe_stamp(const std::string& name);

/// The recipes one thread is computing, outermost first: a recipe whose `in` is a recipe is
/// computed inside the outer one's read. enter() refuses a recipe already on the stack (a
/// loop) or one more than kMaxNesting deep, with `error` naming the chain of recipes.
class RecipeNesting {
public:
    static constexpr int kMaxNesting = 8;
    bool enter(const std::string& key, std::string& error);
    void leave() { m_stack.pop_back(); }
    size_t depth() const { return m_stack.size(); }

private:
    std::vector<std::string> m_stack;
};

}  // namespace mcdn_plugin
