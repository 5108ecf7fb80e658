// Parsing mcdn recipes (recipe.h).
#include "recipe.h"

#include <algorithm>
#include <cctype>
#include <filesystem>
#include <fstream>

#include <sys/stat.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/strutil.h>

#include "mcdn/threads.h"

namespace mcdn_plugin {

using OIIO::Strutil::fmt::format;
namespace Filesystem = OIIO::Filesystem;
namespace Strutil = OIIO::Strutil;

namespace {

const std::vector<std::string> kKeys = { "in",    "seeds",    "variance", "halfA",
                                         "halfB", "preset",   "layer",    "colorspace",
                                         "chain", "channels", "threads" };

// seeds = a.exr,b.exr,...: K renders with different seeds (mcdn::combine_seeds).
std::vector<std::string> seed_paths(const std::string& value)
{
    std::vector<std::string> paths;
    for (const auto& p : Strutil::splits(value, ","))
        if (!Strutil::strip(p).empty())
            paths.push_back(std::string(Strutil::strip(p)));
    return paths;
}

bool is_hex(char c)
{
    return std::isxdigit(static_cast<unsigned char>(c)) != 0;
}

// A comment starts with '#' at the start of a line or after white space, so a path with '#'
// in it (shot#1.exr, oiiotool's frame pattern) stays whole.
std::string without_comment(const std::string& line)
{
    for (size_t i = 0; i < line.size(); ++i)
        if (line[i] == '#' && (i == 0 || std::isspace(static_cast<unsigned char>(line[i - 1]))))
            return line.substr(0, i);
    return line;
}

}  // namespace

std::string url_decode(const std::string& text)
{
    std::string out;
    for (size_t i = 0; i < text.size(); ++i) {
        if (text[i] == '%' && i + 2 < text.size() && is_hex(text[i + 1]) && is_hex(text[i + 2])) {
            out += char(std::stoi(text.substr(i + 1, 2), nullptr, 16));
            i += 2;
        } else
            out += text[i];
    }
    return out;
}

bool parse_recipe_lines(std::istream& in, const std::string& file, Recipe& recipe,
                        std::string& error)
{
    std::string dir = Filesystem::parent_path(file);
    std::string line;
    int number = 0;
    while (std::getline(in, line)) {
        ++number;
        if (number == 1 && Strutil::starts_with(line, "\xEF\xBB\xBF"))  // a UTF-8 BOM
            line = line.substr(3);
        line = Strutil::strip(without_comment(line));
        if (line.empty())
            continue;
        size_t eq = line.find('=');
        if (eq == std::string::npos) {
            error = format("{}:{}: expected key = value", file, number);
            return false;
        }
        std::string key = Strutil::strip(line.substr(0, eq));
        std::string value = Strutil::strip(line.substr(eq + 1));
        // Paths are the recipe's folder's unless absolute.
        auto beside_recipe = [&](const std::string& path) {
            return !path.empty() && path[0] != '/' && !dir.empty() ? dir + "/" + path : path;
        };
        if (key == "in" || key == "variance" || key == "halfA" || key == "halfB")
            value = beside_recipe(value);
        if (key == "seeds") {
            std::vector<std::string> paths = seed_paths(value);
            for (auto& path : paths)
                path = beside_recipe(path);
            value = Strutil::join(paths, ",");
        }
        recipe[key] = value;
    }
    return true;
}

bool parse_query(const std::string& query, Recipe& recipe, std::string& error)
{
    for (const auto& pair : Strutil::splits(query, "&")) {
        size_t eq = pair.find('=');
        if (eq == std::string::npos) {
            error = format("'{}': expected key=value in the query", pair);
            return false;
        }
        std::string key = url_decode(pair.substr(0, eq));
        std::string value = url_decode(pair.substr(eq + 1));
        // %00 would cut the path where the C libraries read it.
        if (key.find('\0') != std::string::npos || value.find('\0') != std::string::npos) {
            error = format("'{}': %00 (a NUL character) in the query", pair);
            return false;
        }
        recipe[key] = value;
    }
    return true;
}

bool parse_recipe(const std::string& name, Recipe& recipe, std::string& error)
{
    size_t q = name.find('?');
    std::string file = name.substr(0, q);
    if (!file.empty() && Filesystem::is_regular(file)) {
        std::ifstream in(file);
        if (!parse_recipe_lines(in, file, recipe, error))
            return false;
    } else if (q == std::string::npos) {
        error = format("{}: no such recipe file, and no ?in=... query", name);
        return false;
    }
    return q == std::string::npos || parse_query(name.substr(q + 1), recipe, error);
}

bool job_from_recipe(const Recipe& recipe, Job& job, std::string& error)
{
    for (const auto& [key, value] : recipe)
        if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end()
            && key.find('.') == std::string::npos) {
            error = format("unknown key '{}' (keys: {}, stage.setting)", key,
                           Strutil::join(kKeys, ", "));
            return false;
        }
    auto get = [&](const std::string& key, const std::string& fallback = "") {
        auto it = recipe.find(key);
        return it == recipe.end() ? fallback : it->second;
    };
    if (get("in").empty() == get("seeds").empty()) {
        error = get("in").empty() ? "no render given: add in=FILE (or seeds=A,B,...)"
                                  : "give in=FILE or seeds=A,B,..., not both";
        return false;
    }
    if (get("in").empty()) {
        const std::vector<std::string> seeds = seed_paths(get("seeds"));
        job.inputs = { mcdn::InputFile(seeds.empty() ? std::string() : seeds[0]) };
        job.inputs[0].seeds = seeds;
    } else {
        job.inputs = { { get("in"), mcdn::InputKind::Mean } };
    }
    for (auto [key, kind] : { std::pair { "variance", mcdn::InputKind::Variance },
                              std::pair { "halfA", mcdn::InputKind::HalfA },
                              std::pair { "halfB", mcdn::InputKind::HalfB } })
        if (!get(key).empty())
            job.inputs.push_back({ get(key), kind });
    job.chain.aovs.preset = get("preset");
    job.chain.aovs.layer = get("layer");
    job.chain.aovs.colorspace = get("colorspace");
    for (const auto& [key, value] : recipe)
        if (key.find('.') != std::string::npos)
            job.chain.settings[key] = value;
    job.channels = Strutil::splits(get("channels"), ",");
    if (!mcdn::parse_threads(get("threads", "0"), job.threads, error))
        return false;
    return mcdn::parse_chain(job.chain.stages, get("chain", "denoise"), error);
}

std::string recipe_key(const std::string& name)
{
    size_t query = name.find('?');
    std::error_code ec;
    std::filesystem::path file =
        std::filesystem::weakly_canonical(std::filesystem::absolute(name.substr(0, query), ec), ec);
    return file.string() + (query == std::string::npos ? "" : name.substr(query));
}

namespace {

// A file as it is now: inode, size and modification time (ns); "-" where it is missing.
std::string file_stamp(const std::string& path)
{
    struct stat st;
    if (::stat(path.c_str(), &st) != 0)
        return "-";
    return format("{}:{}:{}.{}", st.st_ino, st.st_size, st.st_mtim.tv_sec, st.st_mtim.tv_nsec);
}

bool is_recipe_file_name(const std::string& name)
{
    return Strutil::iends_with(name.substr(0, name.find('?')), ".mcdn");
}

void add_stamps(const std::string& name, int depth, std::string& stamps)
{
    const std::string file = name.substr(0, name.find('?'));
    if (!file.empty())
        stamps += file_stamp(file) + ";";
    Recipe recipe;
    std::string error;
    if (!parse_recipe(name, recipe, error))
        return;
    if (auto seeds = recipe.find("seeds"); seeds != recipe.end())
        for (const std::string& seed : seed_paths(seeds->second))
            stamps += file_stamp(seed) + ";";
    for (const char* key : { "in", "variance", "halfA", "halfB" }) {
        auto it = recipe.find(key);
        if (it == recipe.end())
            continue;
        if (is_recipe_file_name(it->second) && depth < RecipeNesting::kMaxNesting)
            add_stamps(it->second, depth + 1, stamps);
        else
            stamps += file_stamp(it->second) + ";";
    }
}

}  // namespace

std::string recipe_stamp(const std::string& name)
{
    std::string stamps;
    add_stamps(name, 0, stamps);
    return stamps;
}

bool RecipeNesting::enter(const std::string& key, std::string& error)
{
    if (std::find(m_stack.begin(), m_stack.end(), key) != m_stack.end()) {
        error = format("recipe loop: {} -> {}", Strutil::join(m_stack, " -> "), key);
        return false;
    }
    if (int(m_stack.size()) >= kMaxNesting) {
        error = format("recipes nested more than {} deep: {} -> {}", kMaxNesting,
                       Strutil::join(m_stack, " -> "), key);
        return false;
    }
    m_stack.push_back(key);
    return true;
}

}  // namespace mcdn_plugin
