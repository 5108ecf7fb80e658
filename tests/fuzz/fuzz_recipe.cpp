// libFuzzer target: the mcdn format plugin's recipes. The first byte picks the form (a URI
// query, or the lines of a recipe file); the rest is the text. A parsed recipe goes on to the
// key checks and the chain's stage names, as the plugin does before it reads any image.
#include <sstream>

#include <OpenImageIO/strutil.h>

#include "recipe.h"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    if (size == 0)
        return 0;
    const bool as_file = data[0] & 1;
    const std::string text(reinterpret_cast<const char*>(data) + 1, size - 1);
    mcdn_plugin::Recipe recipe;
    std::string error;
    bool ok;
    if (as_file) {
        std::istringstream in(text);
        ok = mcdn_plugin::parse_recipe_lines(in, "shots/fuzz.mcdn", recipe, error);
    } else
        ok = mcdn_plugin::parse_query(text, recipe, error);
    mcdn_plugin::Job job;
    if (ok)
        mcdn_plugin::job_from_recipe(recipe, job, error);
    // Nesting: the in= values (comma-separated) entered one inside the other, as recipes
    // whose `in` is a recipe are; never deeper than the limit, never a name twice.
    mcdn_plugin::RecipeNesting nesting;
    size_t entered = 0;
    for (const auto& name : OIIO::Strutil::splits(recipe.count("in") ? recipe["in"] : "", ",", 64))
        if (nesting.enter(name, error))
            ++entered;
        else
            break;
    if (nesting.depth() != entered || int(entered) > mcdn_plugin::RecipeNesting::kMaxNesting)
        __builtin_trap();
    while (nesting.depth() > 0)
        nesting.leave();
    return 0;
}
