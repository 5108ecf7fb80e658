// What a file holds, from its headers alone (io/layout.h): its parts, their channels as the
// merged frame names them, and which EXR reader reads its pixels.
#include "io/layout.h"

#include <algorithm>
#include <cstdlib>
#include <mutex>

#include <OpenEXR/openexr.h>
#include <OpenImageIO/strutil.h>

#include "io/io_steps.h"

namespace mcdn {

using OIIO::ImageInput;
using OIIO::TypeDesc;
namespace Strutil = OIIO::Strutil;
using Strutil::fmt::format;

namespace {

// A part's channel as the merged buffer names it: behind the part's name unless it is the
// first part, has no name, or the channel carries the name already.
std::string part_qualified(const ImageSpec& part, bool first, const std::string& channel)
{
    const std::string name = part.get_string_attribute("name");
    if (first || name.empty() || Strutil::starts_with(channel, name + "."))
        return channel;
    return name + "." + channel;
}

// OpenEXR's C core (OIIO's openexr:core reader) decodes the codecs renderers write most a
// third faster than the C++ library, with the same values. Not for DWAA/DWAB (OpenEXR 3.1's
// core cannot read them) nor B44/B44A (it reads their float channels otherwise):
// tests/core/io_test.cpp checks both readers agree on every codec in this list.
bool core_codec(const ImageSpec& part)
{
    std::string codec = part.get_string_attribute("compression", "none");
    codec = codec.substr(0, codec.find(':'));
    for (const char* read : { "none", "rle", "zips", "zip", "pxr24", "piz" })
        if (codec == read)
            return true;
    return false;
}

// Each of the file's parts' rows per block (OpenEXR's lines per chunk; 1 for a tiled part)
// as the core itself parses the header, or empty where a part has none: OIIO 2.4's core
// reader divides by them, and a damaged header can leave them 0 (a scanline part that
// carries a tile description: tests/fuzz/corpus/exr/scanline_with_tiles.exr).
std::vector<int> core_block_rows(const std::string& path)
{
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = [](exr_const_context_t, exr_result_t, const char*) {};  // quiet
    exr_context_t exr = nullptr;
    std::vector<int> rows;
    int count = 0;
    if (exr_start_read(&exr, path.c_str(), &init) == EXR_ERR_SUCCESS
        && exr_get_count(exr, &count) == EXR_ERR_SUCCESS)
        for (int p = 0; p < count; ++p) {
            exr_storage_t storage = EXR_STORAGE_LAST_TYPE;
            int32_t n = 0;
            if (exr_get_storage(exr, p, &storage) != EXR_ERR_SUCCESS
                || (storage == EXR_STORAGE_SCANLINE
                    && exr_get_scanlines_per_chunk(exr, p, &n) != EXR_ERR_SUCCESS))
                n = 0;
            else if (storage == EXR_STORAGE_TILED)
                n = 1;
            if (n <= 0) {
                rows.clear();
                break;
            }
            rows.push_back(n);
        }
    exr_finish(&exr);
    return rows;
}

// Every part of the file in a codec the core reads, with its blocks as the core sees them
// (FileLayout::core_rows); MCDN_OPENEXR_CORE=0 reads every file with the C++ library.
void choose_reader(FileLayout& layout)
{
    static const bool allowed = [] {
        const char* env = std::getenv("MCDN_OPENEXR_CORE");
        return !env || std::string(env) != "0";
    }();
    layout.core_rows.clear();
    if (!allowed || !layout.exr
        || !std::all_of(layout.parts.begin(), layout.parts.end(), core_codec))
        return;
    const std::vector<int> rows = core_block_rows(layout.path);
    for (int s : layout.subimages)
        layout.core_rows.push_back(s < int(rows.size()) ? rows[s] : 0);
    if (std::find(layout.core_rows.begin(), layout.core_rows.end(), 0) != layout.core_rows.end())
        layout.core_rows.clear();
}

}  // namespace

std::string parts_text(const FileLayout& layout)
{
    std::vector<std::string> lines;
    size_t k = 0;
    for (const ImageSpec& part : layout.parts) {
        std::vector<std::string> fields { part.get_string_attribute("name") };
        for (const std::string& original : part.channelnames) {
            fields.push_back(layout.names[k++]);
            fields.push_back(original);
        }
        lines.push_back(Strutil::join(fields, "\t"));
    }
    return Strutil::join(lines, "\n");
}

bool read_layout(FileLayout& layout, const std::string& path, const std::string& part,
                 std::string& error)
{
    if (!check_input_file(path, error))
        return false;
    auto in = ImageInput::open(path);
    if (!in) {
        error = format("{}: cannot read: {}", path, one_line(OIIO::geterror()));
        return false;
    }
    layout = { path, {}, {}, {}, std::string(in->format_name()) == "openexr", {}, {} };
    std::vector<std::string> part_names;
    const std::vector<std::string> wanted = Strutil::splits(part, ",");
    for (int s = 0; in->seek_subimage(s, 0); ++s) {
        ImageSpec spec = in->spec(s, 0);
        part_names.push_back(spec.get_string_attribute("name"));
        if (!part.empty()
            && std::find(wanted.begin(), wanted.end(), part_names.back()) == wanted.end())
            continue;  // -i:part=NAME[,NAME...] reads those parts alone
        // A recipe read through the mcdn format plugin opens as a placeholder that carries
        // its error (OIIO's procedural inputs cannot fail to open): that error is the file's.
        if (const std::string failed = spec.get_string_attribute("mcdn:error"); !failed.empty()) {
            error = format("{}: {}", path, failed);
            return false;
        }
        if (spec.deep) {
            error = format("{}: deep images are not supported (subimage {})", path, s);
            return false;
        }
        if (!layout.parts.empty() && !same_window(spec.roi(), layout.parts[0].roi())) {
            error =
                format("{}: part {} has data window {}, part {} has {}", path, s,
                       roi_text(spec.roi()), layout.subimages[0], roi_text(layout.parts[0].roi()));
            return false;
        }
        for (int c = 0; c < spec.nchannels; ++c)
            layout.types.push_back(spec.channelformat(c));
        spec.set_format(TypeDesc::FLOAT);
        spec.channelformats.clear();
        layout.parts.push_back(spec);
        layout.subimages.push_back(s);
    }
    if (layout.parts.empty() && !part.empty()) {
        error = format("{}: no part named '{}' (parts: {})", path, Strutil::join(wanted, "' or '"),
                       Strutil::join(part_names, ", "));
        return false;
    }
    if (layout.parts.empty()) {
        error = format("{}: no image in file", path);
        return false;
    }
    // The first part's channels keep their names (what a reader of part 0 alone sees: the
    // beauty, in a renderer's multi-part file); the other parts' go behind their part's name.
    for (size_t p = 0; p < layout.parts.size(); ++p)
        for (const auto& ch : layout.parts[p].channelnames)
            layout.names.push_back(part_qualified(layout.parts[p], p == 0, ch));
    choose_reader(layout);
    return true;
}

bool core_reads(const FileLayout& layout)
{
    return !layout.core_rows.empty();
}

// The file opened for its pixels: OIIO picks the EXR reader when it creates one, from a
// global attribute, so the attribute is set for this open alone (and put back).
std::unique_ptr<ImageInput> open_for_pixels(const FileLayout& layout)
{
    if (!core_reads(layout))
        return ImageInput::open(layout.path);
    static std::mutex mutex;
    std::lock_guard<std::mutex> lock(mutex);
    int before = 0;
    OIIO::getattribute("openexr:core", before);
    OIIO::attribute("openexr:core", 1);
    std::unique_ptr<ImageInput> in = ImageInput::open(layout.path);
    OIIO::attribute("openexr:core", before);
    return in;
}

}  // namespace mcdn
