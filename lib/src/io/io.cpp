// Reading renders into one merged float buffer, checking their values, writing results
// through a temporary file.
#include "mcdn/io.h"

#include <algorithm>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cctype>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <cstdlib>
#include <map>
#include <memory>
#include <mutex>
#include <set>

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include "aov/transmission.h"
#include "core/attributes.h"
#include "core/op_prepare.h"
#include "core/planar.h"

namespace mcdn {

using OIIO::ImageInput;
using OIIO::ImageOutput;
using OIIO::TypeDesc;
namespace Filesystem = OIIO::Filesystem;
namespace Strutil    = OIIO::Strutil;
using Strutil::fmt::format;

namespace {

// Copies every channel of `src` into `dst` starting at channel `first`: dst's rows, which
// src holds (same columns, float).
void copy_channels(ImageBuf& dst, int first, const ImageBuf& src)
{
    const int nsrc = src.nchannels(), ndst = dst.nchannels();
    const float* in = static_cast<const float*>(src.localpixels())
                      + size_t(dst.spec().y - src.spec().y) * src.spec().width * nsrc;
    float* out = static_cast<float*>(dst.localpixels());
    const size_t npixels = dst.spec().image_pixels();
    for (size_t p = 0; p < npixels; ++p)
        for (int c = 0; c < nsrc; ++c)
            out[p * ndst + first + c] = in[p * nsrc + c];
}

// Same pixel window, whatever the channel counts.
bool same_window(const ROI& a, const ROI& b)
{
    return a.xbegin == b.xbegin && a.xend == b.xend && a.ybegin == b.ybegin && a.yend == b.yend;
}

std::string roi_text(const ROI& roi)
{
    return format("{}x{} at ({},{})", roi.width(), roi.height(), roi.xbegin, roi.ybegin);
}

// An OIIO error as one line of ours: it may hold several, one per problem it found.
std::string one_line(std::string text)
{
    while (!text.empty() && (text.back() == '\n' || text.back() == ' '))
        text.pop_back();
    return Strutil::replace(text, "\n", "; ", true);
}

// A part's channel as the merged buffer names it: behind the part's name unless it is the
// first part, has no name, or the channel carries the name already.
std::string part_qualified(const ImageSpec& part, bool first, const std::string& channel)
{
    const std::string name = part.get_string_attribute("name");
    if (first || name.empty() || Strutil::starts_with(channel, name + "."))
        return channel;
    return name + "." + channel;
}

// A file's channels as read_image names them, from its header alone: each part's float spec
// and, in order, every part's channels (part_qualified).
struct FileLayout {
    std::string path;
    std::vector<ImageSpec> parts;
    std::vector<std::string> names;
    std::vector<int> subimages;  // each part's subimage in the file
    bool exr = false;

    // The merged buffer's spec: the first part's metadata with every part's channels.
    ImageSpec merged_spec() const
    {
        ImageSpec spec = parts[0];
        spec.nchannels = int(names.size());
        spec.channelnames = names;
        if (parts.size() > 1)
            spec.alpha_channel = spec.z_channel = -1;
        return spec;
    }
};

// The parts of a multi-part render, kept in the merged buffer so that write_image writes
// the same parts: a line per part, its name then pairs of merged and original channel names,
// tab-separated.
constexpr const char* kPartsAttribute = "mcdn:parts";
// Set when read_inputs read no half-buffer channel (InputSelection::halves false).
constexpr const char* kHalvesUnread = "mcdn:halves_unread";

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

struct Part {
    std::string name;
    std::vector<std::pair<std::string, std::string>> channels;  // merged, original
};

std::vector<Part> parse_parts(const std::string& text)
{
    std::vector<Part> parts;
    for (const std::string& line : Strutil::splits(text, "\n")) {
        std::vector<std::string> fields = Strutil::splits(line, "\t");
        if (fields.empty())
            continue;
        Part part { fields[0], {} };
        for (size_t i = 1; i + 1 < fields.size(); i += 2)
            part.channels.emplace_back(fields[i], fields[i + 1]);
        parts.push_back(std::move(part));
    }
    return parts;
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
    layout = { path, {}, {}, {}, std::string(in->format_name()) == "openexr" };
    std::vector<std::string> part_names;
    for (int s = 0; in->seek_subimage(s, 0); ++s) {
        ImageSpec spec = in->spec(s, 0);
        part_names.push_back(spec.get_string_attribute("name"));
        if (!part.empty() && part_names.back() != part)
            continue;  // -i:part=NAME reads that part alone
        // A recipe read through the mcdn format plugin opens as a placeholder that carries
        // its error (OIIO's procedural inputs cannot fail to open): that error is the file's.
        if (const std::string failed = spec.get_string_attribute("mcdn:error");
            !failed.empty()) {
            error = format("{}: {}", path, failed);
            return false;
        }
        if (spec.deep) {
            error = format("{}: deep images are not supported (subimage {})", path, s);
            return false;
        }
        if (!layout.parts.empty() && !same_window(spec.roi(), layout.parts[0].roi())) {
            error = format("{}: part {} has data window {}, part {} has {}", path, s,
                           roi_text(spec.roi()), layout.subimages[0],
                           roi_text(layout.parts[0].roi()));
            return false;
        }
        spec.set_format(TypeDesc::FLOAT);
        spec.channelformats.clear();
        layout.parts.push_back(spec);
        layout.subimages.push_back(s);
    }
    if (layout.parts.empty() && !part.empty()) {
        error = format("{}: no part named '{}' (parts: {})", path, part,
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
    return true;
}

// OpenEXR's C core (OIIO's openexr:core reader) decodes the codecs renderers write most a
// third faster than the C++ library, with the same values. Not for DWAA/DWAB (OpenEXR 3.1's
// core cannot read them) nor B44/B44A (it reads their float channels otherwise):
// tests/core/io_test.cpp checks both readers agree on every codec in this list.
// The rows of one block (OpenEXR's lines per chunk) of a part stored with a codec the core
// reads, else 0.
int core_block_rows(const ImageSpec& part)
{
    std::string codec = part.get_string_attribute("compression", "none");
    codec = codec.substr(0, codec.find(':'));
    if (codec == "none" || codec == "rle" || codec == "zips")
        return 1;
    if (codec == "zip" || codec == "pxr24")
        return 16;
    return codec == "piz" ? 32 : 0;
}

// Every part of the file in a codec the core reads (core_block_rows);
// MCDN_OPENEXR_CORE=0 reads every file with the C++ library.
bool core_reads(const FileLayout& layout)
{
    static const bool allowed = [] {
        const char* env = std::getenv("MCDN_OPENEXR_CORE");
        return !env || std::string(env) != "0";
    }();
    return allowed && layout.exr
           && std::all_of(layout.parts.begin(), layout.parts.end(),
                          [](const ImageSpec& part) { return core_block_rows(part) > 0; });
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

// OIIO leaves a buffer without pixels (and says so only on its debug channel) when memory
// runs out: an error naming the file and the size, instead of writing through null.
bool allocated(const ImageBuf& buf, const std::string& path, std::string& error)
{
    if (buf.localpixels())
        return true;
    const ImageSpec& spec = buf.spec();
    error = format("{}: out of memory for a {}x{} frame of {} float channels ({:.1f} GB)", path,
                   spec.width, spec.height, spec.nchannels, double(spec.image_bytes()) / 1e9);
    return false;
}

// Reads rows [y0, y1) of the file's channels into dst (which holds those rows) from channel
// `first` on: every channel, or those `keep` marks (in the layout's order). A scanline part
// whose channels are all kept goes straight into dst with strides (no buffer per file, so
// merging costs the merged rows only); otherwise the part is read in bands of rows, all of its
// channels at once (an EXR block holds every channel: one decode per block), and the kept ones
// copied out.
bool read_pixels_into(ImageBuf& dst, int first, const FileLayout& layout, ImageInput& in,
                      const std::vector<bool>& keep, int y0, int y1, std::string& error)
{
    auto failed = [&] {
        error = format("{}: cannot read pixels (truncated or corrupt?): {}", layout.path,
                       one_line(in.geterror()));
        return false;
    };
    const int total = dst.nchannels();
    const OIIO::stride_t pixel = OIIO::stride_t(total) * sizeof(float);
    const bool core = core_reads(layout);
    float* out = static_cast<float*>(dst.localpixels()) + first;
    size_t k = 0;  // index into keep over every part's channels
    std::vector<float> rows;
    for (size_t s = 0; s < layout.parts.size(); ++s) {
        const ImageSpec& part = layout.parts[s];
        const int n = part.nchannels;
        std::vector<int> kept;
        for (int c = 0; c < n; ++c, ++k)
            if (keep.empty() || keep[k])
                kept.push_back(c);
        if (kept.empty())
            continue;
        // A tiled file (Arnold's and RenderMan's EXRs often are) is read in rows of whole
        // tiles: OIIO reads tiles, not scanlines, from it. OpenEXR's core reader is asked
        // for whole blocks of rows too: OIIO 2.4 reads a range that starts or ends inside a
        // block through a buffer it allocates with new[] and frees with delete.
        const bool tiled = part.tile_width > 0 && part.tile_height > 0;
        const int aligned = tiled ? part.tile_height : core ? core_block_rows(part) : 1;
        if (!tiled && aligned == 1 && int(kept.size()) == n) {
            if (!in.read_scanlines(layout.subimages[s], 0, y0, y1, part.z, 0, n, TypeDesc::FLOAT,
                                   out, pixel, pixel * part.width))
                return failed();
            out += n;
            continue;
        }
        int band = std::max(1, int((int64_t(1) << 22) / (int64_t(part.width) * n)));
        band = std::max(1, band / aligned) * aligned;
        const int first_row = part.y + (y0 - part.y) / aligned * aligned;
        const int last_row = part.y + (y1 - part.y + aligned - 1) / aligned * aligned;
        for (int y = first_row; y < y1; y += band) {
            const int end = std::min({ part.y + part.height, last_row, y + band });
            rows.resize(size_t(end - y) * part.width * n);
            const bool read
                = tiled ? in.read_tiles(layout.subimages[s], 0, part.x, part.x + part.width, y,
                                        end, part.z, part.z + std::max(part.depth, 1), 0, n,
                                        TypeDesc::FLOAT, rows.data())
                        : in.read_scanlines(layout.subimages[s], 0, y, end, part.z, 0, n,
                                            TypeDesc::FLOAT, rows.data());
            if (!read)
                return failed();
            for (int row = std::max(y, y0); row < std::min(end, y1); ++row)
                for (int x = 0; x < part.width; ++x) {
                    float* to = out + (size_t(row - y0) * part.width + x) * total;
                    const float* from = rows.data() + (size_t(row - y) * part.width + x) * n;
                    for (size_t j = 0; j < kept.size(); ++j)
                        to[j] = from[kept[j]];
                }
        }
        out += kept.size();
    }
    return true;
}

}  // namespace

bool check_input_file(const std::string& path, std::string& error)
{
    struct stat st;
    if (::stat(path.c_str(), &st) != 0) {
        error = errno == ENOENT ? format("{}: no such file", path)
                                : format("{}: cannot read: {}", path, std::strerror(errno));
        return false;
    }
    if (S_ISDIR(st.st_mode)) {
        error = format("{}: is a folder, not a file", path);
        return false;
    }
    // OIIO probes a file by reading it: a FIFO or a device would block it, or feed it
    // without end.
    if (!S_ISREG(st.st_mode)) {
        error = format("{}: not a regular file ({}): give a file on disk", path,
                       S_ISFIFO(st.st_mode)   ? "a FIFO"
                       : S_ISSOCK(st.st_mode) ? "a socket"
                                              : "a device");
        return false;
    }
    // OIIO reports an unreadable file as not being in any format it knows.
    if (::access(path.c_str(), R_OK) != 0) {
        error = format("{}: cannot read: {}", path, std::strerror(errno));
        return false;
    }
    return true;
}

bool read_image(ImageBuf& dst, const std::string& path)
{
    FileLayout layout;
    std::string error;
    if (!read_layout(layout, path, "", error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    ImageBuf out(layout.merged_spec());
    auto in = open_for_pixels(layout);
    if (!in) {
        dst.errorfmt("{}: cannot read: {}", path, one_line(OIIO::geterror()));
        return false;
    }
    const ROI window = layout.parts[0].roi();
    if (!allocated(out, path, error)
        || !read_pixels_into(out, 0, layout, *in, {}, window.ybegin, window.yend, error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    dst = std::move(out);
    return true;
}

bool read_tungsten_directory(ImageBuf& dst, const std::string& dir)
{
    // buffer file stem -> channel names in the generic layout
    struct Buffer {
        const char* stem;
        std::vector<std::string> channels;
    };
    const Buffer buffers[] = {
        { "color", { "R", "G", "B" } },
        { "albedo", { "albedo.R", "albedo.G", "albedo.B" } },
        { "normal", { "N.X", "N.Y", "N.Z" } },
        { "depth", { "Z" } },
        { "visibility", { "visibility" } },
    };
    const std::pair<const char*, InputKind> faces[] = {
        { "", InputKind::Mean },
        { "Variance", InputKind::Variance },
        { "A", InputKind::HalfA },
        { "B", InputKind::HalfB },
    };

    std::vector<ImageBuf> pieces;
    std::vector<std::string> names;
    for (const auto& buffer : buffers) {
        for (const auto& [suffix, kind] : faces) {
            std::string file = format("{}/{}{}.pfm", dir, buffer.stem, suffix);
            if (!Filesystem::exists(file)) {
                if (std::string(buffer.stem) == "color" && kind == InputKind::Mean) {
                    dst.errorfmt("{}: not a Tungsten buffer directory (no color.pfm)", dir);
                    return false;
                }
                continue;
            }
            ImageBuf piece;
            if (!read_image(piece, file)) {
                dst.errorfmt("{}", piece.geterror());
                return false;
            }
            int n = int(buffer.channels.size());
            if (piece.nchannels() < n) {
                dst.errorfmt("{}: has {} channel(s), {} needs {}", file, piece.nchannels(),
                             buffer.stem, n);
                return false;
            }
            if (!pieces.empty() && !same_window(piece.roi(), pieces[0].roi())) {
                dst.errorfmt("{}: size {} differs from color.pfm's {}", file,
                             roi_text(piece.roi()), roi_text(pieces[0].roi()));
                return false;
            }
            pieces.push_back(OIIO::ImageBufAlgo::channels(piece, n, {}));
            for (const auto& ch : buffer.channels)
                names.push_back(input_kind_prefix(kind) + ch);
        }
    }
    ImageSpec spec(pieces[0].roi(), TypeDesc::FLOAT);
    spec.nchannels = int(names.size());
    spec.channelnames = names;
    spec.alpha_channel = spec.z_channel = -1;
    ImageBuf out(spec);
    int first = 0;
    for (const auto& piece : pieces) {
        copy_channels(out, first, piece);
        first += piece.nchannels();
    }
    dst = std::move(out);
    return true;
}

bool read_inputs(ImageBuf& dst, const std::vector<InputFile>& inputs)
{
    return read_inputs(dst, inputs, InputSelection());
}

namespace {

// A file given as the variance or a half must supply that face of the colour: one that does
// not (a PNG renamed var.exr, a layer without Combined.B) would be ignored and the stages
// would run without it. Only the channel names are looked at; `halves` false skips the half
// files.
bool check_colour_faces(const ImageSpec& spec, const AovSet& aovs, bool halves,
                        std::string& error)
{
    for (const InputFile& file : merged_input_files(spec)) {
        if (file.kind == InputKind::Mean || (!halves && file.kind != InputKind::Variance))
            continue;
        const Role role = file.kind == InputKind::Variance ? Role::ColorVariance
                          : file.kind == InputKind::HalfA  ? Role::ColorA
                                                           : Role::ColorB;
        std::string why;
        if (!aovs.require({ role }, spec, why)) {
            error = format("{}: given with -i:as={} but has no {} of the colour: {}", file.path,
                           input_kind_name(file.kind),
                           file.kind == InputKind::Variance ? "variance" : "half buffer", why);
            return false;
        }
    }
    return true;
}

// The light components only the CNN reads (InputSelection::light_split).
bool is_light_split(Role r)
{
    return r == Role::Diffuse || r == Role::Specular || r == Role::DiffuseColor
           || r == Role::DiffuseDirect || r == Role::DiffuseIndirect || r == Role::GlossyColor
           || r == Role::GlossyDirect || r == Role::GlossyIndirect || r == Role::Emission
           || r == Role::Environment;
}

// The variance and half-buffer channels `selection` keeps of a merged buffer's full list of
// names (`spec`, before any pixel is read).
std::set<std::string> selected_faces(const ImageSpec& spec, const InputSelection& selection,
                                     std::string& error)
{
    std::set<std::string> wanted;
    AovSet aovs;
    std::string unresolved;
    if (!resolve_aovs(aovs, selection.aovs, spec, unresolved)) {
        for (const auto& name : spec.channelnames)  // the ops will say what is wrong
            wanted.insert(name);
        return wanted;
    }
    auto add = [&](const std::vector<int>& channels) {
        for (int c : channels)
            wanted.insert(spec.channelnames[c]);
    };
    for (int r = 0; r < kRoleCount; ++r)
        if (selection.light_split || !is_light_split(Role(r)))
            add(aovs.channels(Role(r)));
    for (const AovSet::Extra& e : aovs.extras())
        add(e.channels);
    // Cycles' transmission passes, which the CNN reads by name (aov/transmission.h): without
    // their faces it would see an incomplete split, and a run would denoise differently from
    // one that reads every channel (a --ch of the variance file's).
    for (const char* pass : kTransmissionPasses)
        for (const std::string& name : transmission_channels(aovs.names(Role::DiffuseColor), pass))
            if (selection.light_split && spec.channelindex(name) >= 0)
                wanted.insert(name);
    // Every face of each of them: roles without faces of their own (Blender's DiffCol,
    // GlossDir, ...) have their variance read by name too (the CNN's delta method).
    std::vector<std::string> means(selection.extra_features);
    for (const std::string& name : wanted)
        means.push_back(name);
    for (const std::string& name : means)
        for (InputKind k : { InputKind::Variance, InputKind::HalfA, InputKind::HalfB })
            wanted.insert(input_kind_prefix(k) + name);
    // Without halves none is read (the half files are not even decoded): that each half file
    // supplies the colour's half is checked here, from the headers, not by validate_inputs.
    if (!selection.halves) {
        if (!check_colour_faces(spec, aovs, true, error))
            return {};
        for (auto it = wanted.begin(); it != wanted.end();)
            it = Strutil::starts_with(*it, input_kind_prefix(InputKind::HalfA))
                         || Strutil::starts_with(*it, input_kind_prefix(InputKind::HalfB))
                     ? wanted.erase(it)
                     : std::next(it);
    }
    return wanted;
}

}  // namespace

struct InputRows::Files {
    std::vector<InputFile> inputs;
    std::vector<FileLayout> layouts;
    std::vector<ImageBuf> directories;  // Tungsten buffer sets, read whole
    std::vector<std::vector<bool>> keep;
    std::vector<int> first;  // each file's first channel in the merged frame
};

InputRows::InputRows() = default;
InputRows::~InputRows() = default;
InputRows::InputRows(InputRows&&) noexcept = default;
InputRows& InputRows::operator=(InputRows&&) noexcept = default;

bool InputRows::open(const std::vector<InputFile>& inputs, const InputSelection& selection,
                     std::string& error)
{
    m_files.reset();
    m_spec = ImageSpec();
    if (inputs.empty()) {
        error = "no input image: give one with -i FILE";
        return false;
    }
    // Headers only: every name and window is checked before any pixel is read.
    auto files = std::make_unique<Files>();
    files->inputs = inputs;
    std::vector<FileLayout>& layouts = files->layouts;
    std::vector<ImageBuf>& directories = files->directories;
    layouts.resize(inputs.size());
    directories.resize(inputs.size());
    std::vector<std::string> names, provenance, output_channels;
    std::map<std::string, std::string> channel_file;
    for (size_t i = 0; i < inputs.size(); ++i) {
        const InputFile& input = inputs[i];
        bool is_dir = Filesystem::is_directory(input.path);
        if (is_dir && input.kind != InputKind::Mean) {
            error = format("{}: a Tungsten buffer directory holds every face itself; give it "
                           "as a plain -i", input.path);
            return false;
        }
        if (is_dir) {
            if (!read_tungsten_directory(directories[i], input.path)) {
                error = directories[i].geterror();
                return false;
            }
            const ImageSpec& spec = directories[i].spec();
            layouts[i] = { input.path, { spec }, spec.channelnames, { 0 } };
        } else if (!read_layout(layouts[i], input.path, input.part, error)) {
            return false;
        }
        const ROI window = layouts[i].parts[0].roi(), first_window = layouts[0].parts[0].roi();
        if (!same_window(window, first_window)) {
            error = format("{}: data window {} differs from {}'s {}", input.path,
                           roi_text(window), inputs[0].path, roi_text(first_window));
            return false;
        }
        for (const auto& ch : layouts[i].names) {
            std::string name = input_kind_prefix(input.kind) + ch;
            if (channel_file.count(name)) {
                error = format("{}: channel '{}' is also in {}; give each input once, with "
                               "-i:as=variance|halfA|halfB for the other faces",
                               input.path, name, channel_file[name]);
                return false;
            }
            channel_file[name] = input.path;
            names.push_back(name);
            if (input.kind == InputKind::Mean)
                output_channels.push_back(name);
        }
        provenance.push_back(format("{}={}", input_kind_name(input.kind), input.path));
    }

    // Only the variance and half channels the selection wants (the render's: all of them).
    std::vector<std::vector<bool>>& keep = files->keep;
    keep.resize(inputs.size());
    for (size_t i = 0; i < inputs.size(); ++i)
        keep[i].assign(layouts[i].names.size(), true);
    if (selection.only_roles) {
        ImageSpec all;
        all.channelnames = names;
        all.nchannels = int(names.size());
        all.attribute("mcdn:inputs", Strutil::join(provenance, "\n"));
        const std::set<std::string> wanted = selected_faces(all, selection, error);
        if (!error.empty())
            return false;
        names.clear();
        for (size_t i = 0; i < inputs.size(); ++i)
            for (size_t c = 0; c < layouts[i].names.size(); ++c) {
                const std::string name = input_kind_prefix(inputs[i].kind) + layouts[i].names[c];
                keep[i][c] = inputs[i].kind == InputKind::Mean || directories[i].initialized()
                             || wanted.count(name);
                if (keep[i][c])
                    names.push_back(name);
            }
    }
    int first = 0;
    for (size_t i = 0; i < inputs.size(); ++i) {
        files->first.push_back(first);
        first += int(std::count(keep[i].begin(), keep[i].end(), true));
    }

    // The first mean input's metadata (colour space, camera, renderer) is the output's.
    size_t meta_from = 0;
    for (size_t i = 0; i < inputs.size(); ++i)
        if (inputs[i].kind == InputKind::Mean) {
            meta_from = i;
            break;
        }
    ImageSpec spec = layouts[meta_from].merged_spec();
    spec.set_format(TypeDesc::FLOAT);
    spec.channelformats.clear();
    spec.nchannels = int(names.size());
    spec.channelnames = names;
    spec.alpha_channel = spec.z_channel = -1;
    spec.attribute("mcdn:inputs", Strutil::join(provenance, "\n"));
    if (selection.only_roles && !selection.halves)
        spec.attribute(kHalvesUnread, 1);
    // A multi-part render is written back with the same parts (write_image).
    if (layouts[meta_from].parts.size() > 1)
        spec.attribute(kPartsAttribute, parts_text(layouts[meta_from]));
    spec.attribute(kOutputChannelsAttribute, Strutil::join(output_channels, "\n"));
    m_spec = spec;
    m_files = std::move(files);
    return true;
}

bool InputRows::read(ImageBuf& dst, int ybegin, int yend, std::string& error,
                     const std::vector<bool>& channels) const
{
    if (!m_files) {
        error = "InputRows::read: no inputs opened";
        return false;
    }
    Files& f = *m_files;
    if (ybegin < m_spec.y || yend > m_spec.y + m_spec.height || ybegin >= yend) {
        error = format("InputRows::read: rows [{}, {}) outside the frame's [{}, {})", ybegin,
                       yend, m_spec.y, m_spec.y + m_spec.height);
        return false;
    }
    ImageSpec spec = m_spec;
    spec.y = ybegin;
    spec.height = yend - ybegin;
    // Not zero-filled when every file is read: the files fill every channel (a fill would
    // be a pass more). A buffer of the same shape is read into again (no fresh pages: a light
    // pass reads the frame through one), also one with more channels after the frame's (room
    // a caller made for its own: they are left as they are).
    const bool every_file = channels.empty();
    ImageBuf out;
    if (dst.localpixels() && dst.spec().format == TypeDesc::FLOAT
        && dst.spec().nchannels >= spec.nchannels && dst.spec().width == spec.width
        && dst.spec().height == spec.height && dst.spec().x == spec.x
        && std::equal(spec.channelnames.begin(), spec.channelnames.end(),
                      dst.spec().channelnames.begin())) {
        out = std::move(dst);
        out.set_origin(spec.x, spec.y, spec.z);
    } else {
        if (!allocate_frame(out, spec, !every_file)) {
            out.geterror();  // said below, naming the file
            allocated(out, f.inputs[0].path, error);
            return false;
        }
    }
    for (size_t i = 0; i < f.inputs.size(); ++i) {
        const int first = f.first[i];
        const int count = int(std::count(f.keep[i].begin(), f.keep[i].end(), true));
        if (!every_file
            && std::none_of(channels.begin() + first, channels.begin() + first + count,
                            [](bool b) { return b; }))
            continue;  // none of its channels wanted: the file is not decoded
        if (f.directories[i].initialized()) {
            copy_channels(out, first, f.directories[i]);
            continue;
        }
        // Opened for these rows and closed after them: an open EXR holds line buffers of
        // its own for each decoding thread (tens of MB a file at 4K), which would otherwise
        // stay beside the band through the stages. Headers are read again for each band.
        std::unique_ptr<ImageInput> in = open_for_pixels(f.layouts[i]);
        if (!in) {
            error = format("{}: cannot read: {}", f.layouts[i].path,
                           one_line(OIIO::geterror()));
            return false;
        }
        const ImageSpec& part = f.layouts[i].parts[0];
        const ImageSpec& now = in->spec(f.layouts[i].subimages[0]);
        if (now.width != part.width || now.height != part.height || now.x != part.x
            || now.y != part.y || now.channelnames != part.channelnames) {
            error = format("{}: the file changed while it was read (it is now {}x{}, {} "
                           "channel(s))", f.layouts[i].path, now.width, now.height,
                           now.nchannels);
            return false;
        }
        if (!read_pixels_into(out, first, f.layouts[i], *in, f.keep[i], ybegin, yend, error))
            return false;
    }
    dst = std::move(out);
    return true;
}

bool read_inputs(ImageBuf& dst, const std::vector<InputFile>& inputs,
                 const InputSelection& selection)
{
    // Headers first: every name and window is checked and the merged frame allocated before
    // any pixel is read; then each file reads straight into it (an 8K frame of 40 channels
    // peaks at its own 5.3 GB, not twice that).
    InputRows rows;
    std::string error;
    if (!rows.open(inputs, selection, error)
        || !rows.read(dst, rows.spec().y, rows.spec().y + rows.spec().height, error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    return true;
}

std::vector<InputFile> merged_input_files(const ImageSpec& merged)
{
    std::vector<InputFile> files;
    for (const auto& line : Strutil::splits(merged.get_string_attribute("mcdn:inputs"), "\n")) {
        size_t eq = line.find('=');
        auto kind = eq == std::string::npos ? std::nullopt
                                            : input_kind_from_name(line.substr(0, eq));
        if (kind)
            files.push_back({ line.substr(eq + 1), *kind });
    }
    return files;
}

bool validate_inputs(const ImageBuf& merged, const AovSet& aovs, std::string& error)
{
    const ImageSpec& spec = merged.spec();
    const int nch = spec.nchannels;
    const float* pixels = static_cast<const float*>(merged.localpixels());
    if (!pixels || spec.format != TypeDesc::FLOAT) {
        error = "validate_inputs: expects a local float buffer (use read_inputs)";
        return false;
    }
    // Half files whose channels read_inputs did not read it checked from their headers.
    if (!check_colour_faces(spec, aovs, spec.get_int_attribute(kHalvesUnread) != 1, error))
        return false;
    auto is_variance = [](Role r) {
        return r == Role::ColorVariance || r == Role::AlbedoVariance
               || r == Role::NormalVariance || r == Role::DepthVariance
               || r == Role::VisibilityVariance;
    };
    auto nan_allowed = [&](Role r) { return is_variance(r) && r != Role::ColorVariance; };
    auto problem_of = [&](Role role, float v) -> const char* {
        if (std::isnan(v) && !nan_allowed(role))
            return "NaN";
        if (std::isinf(v))
            return "Inf";
        if (std::fabs(v) > kHugeValue)
            return "a huge value (|v| > 1e15)";
        if (is_variance(role) && v < 0.0f)
            return "a negative variance";
        return nullptr;
    };
    const size_t npixels = spec.image_pixels();
    // One pass over the pixels finds whether anything is wrong (a pass per channel would
    // read the whole frame once per role channel); only then the channel-by-channel scan
    // below names the first problem.
    std::vector<std::pair<Role, int>> checked;
    // Motion vectors are not checked: only the cross-frame modes read them, and those take a
    // non-finite vector as no motion (core/motion.h).
    for (int r = 0; r < kRoleCount; ++r)
        if (Role(r) != Role::Motion)
            for (int c : aovs.channels(Role(r)))
                checked.emplace_back(Role(r), c);
    bool clean = true;
    for (size_t p = 0; p < npixels && clean; ++p)
        for (const auto& [role, c] : checked)
            if (problem_of(role, pixels[p * nch + c])) {
                clean = false;
                break;
            }
    // Normals: their length (a sum over three channels), in the same pass's order.
    const std::vector<int>& normal = aovs.channels(Role::Normal);
    for (size_t p = 0; p < npixels && clean && normal.size() == 3; ++p) {
        const float* px = pixels + p * nch;
        const float length = std::sqrt(px[normal[0]] * px[normal[0]]
                                       + px[normal[1]] * px[normal[1]]
                                       + px[normal[2]] * px[normal[2]]);
        if (length > kMaxNormalLength) {
            int x = spec.x + int(p % spec.width), y = spec.y + int(p / spec.width);
            error = format("{}: channel '{}' (role normal) has a normal of length {:.3g} at "
                           "pixel ({}, {}), not a direction (at most {}): give unit normals, "
                           "or drop the pass",
                           channel_source(spec, spec.channelnames[normal[0]]),
                           spec.channelnames[normal[0]], length, x, y, kMaxNormalLength);
            return false;
        }
    }
    if (clean)
        return true;
    for (int r = 0; r < kRoleCount; ++r) {
        Role role = Role(r);
        if (role == Role::Motion)
            continue;
        for (int c : aovs.channels(role)) {
            for (size_t p = 0; p < npixels; ++p) {
                const char* problem = problem_of(role, pixels[p * nch + c]);
                if (!problem)
                    continue;
                int x = spec.x + int(p % spec.width), y = spec.y + int(p / spec.width);
                error = format("{}: channel '{}' (role {}) has {} at pixel ({}, {}): "
                               "fix the render or drop the pass",
                               channel_source(spec, spec.channelnames[c]),
                               spec.channelnames[c], role_name(role), problem, x, y);
                return false;
            }
        }
    }
    return true;
}

namespace {

namespace fs = std::filesystem;

// The temporary files of the writes in progress, for remove_temporary_outputs() in a signal
// handler: fixed slots (no allocation there), each free, being filled, or armed.
struct TemporarySlot {
    std::atomic<int> state { 0 };  // 0 free, 1 being filled, 2 armed
    char path[4096];
};
TemporarySlot g_temporaries[64];

// Holds `path` in a slot while it exists on disk; false (no slot, or too long a path) only
// means a signal could not remove it: a later write for the same output will.
class TemporaryRegistration {
public:
    explicit TemporaryRegistration(const std::string& path)
    {
        if (path.size() >= sizeof(TemporarySlot::path))
            return;
        for (auto& slot : g_temporaries) {
            int expected = 0;
            if (slot.state.compare_exchange_strong(expected, 1)) {
                std::memcpy(slot.path, path.c_str(), path.size() + 1);
                slot.state.store(2);
                m_slot = &slot;
                return;
            }
        }
    }
    ~TemporaryRegistration()
    {
        if (m_slot)
            m_slot->state.store(0);
    }
    TemporaryRegistration(const TemporaryRegistration&) = delete;
    TemporaryRegistration& operator=(const TemporaryRegistration&) = delete;

private:
    TemporarySlot* m_slot = nullptr;
};

// `.NAME.mcdn-tmp-` in the folder of `path`: what every temporary of that output starts with.
std::string temporary_prefix(const std::string& path)
{
    fs::path p(path);
    return (p.parent_path() / ("." + p.filename().string() + ".mcdn-tmp-")).string();
}

// How long a temporary nobody can be shown to own is left alone: a writer on another host
// (or in another container) touches its file at least once a band, far more often.
constexpr auto kStaleTemporaryAge = std::chrono::hours(24);

// Removes the temporaries of `path` that a dead writer left: what SIGKILL, a power cut or a
// crash left behind. A temporary's name holds its writer's PID and temporary_owner(); a PID
// is only checked where it means this host's process, in this PID namespace (on shared
// storage another node's or another container's PID names nothing here: its live writer
// would lose its work). A temporary of another owner, or an unowned one, goes only when it
// has not been written for kStaleTemporaryAge.
void remove_stale_temporaries(const std::string& path)
{
    const std::string prefix = temporary_prefix(path);
    const fs::path dir = fs::path(prefix).parent_path();
    const std::string start = fs::path(prefix).filename().string();
    const std::string owner = temporary_owner();
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(dir.empty() ? fs::path(".") : dir, ec)) {
        std::string name = entry.path().filename().string();
        if (name.compare(0, start.size(), start) != 0)
            continue;
        // PID-N-OWNER
        const char* text = name.c_str() + start.size();
        char* end = nullptr;
        const long pid = std::strtol(text, &end, 10);
        if (*end == '-')
            std::strtol(end + 1, &end, 10);
        const bool ours = *end == '-' && owner == end + 1;
        bool stale = false;
        if (ours)
            stale = pid > 0 && pid != long(::getpid()) && ::kill(pid_t(pid), 0) != 0
                    && errno == ESRCH;
        else {
            const auto written = fs::last_write_time(entry.path(), ec);
            stale = !ec && fs::file_time_type::clock::now() - written > kStaleTemporaryAge;
        }
        if (stale)
            fs::remove(entry.path(), ec);
    }
}

// The same file: the same device and inode when both exist (hard links, symlinks, ./a and
// a), else the same absolute, normalised name.
bool same_file(const std::string& a, const std::string& b)
{
    struct stat sa, sb;
    if (::stat(a.c_str(), &sa) == 0 && ::stat(b.c_str(), &sb) == 0)
        return sa.st_dev == sb.st_dev && sa.st_ino == sb.st_ino;
    std::error_code ec;
    return fs::weakly_canonical(fs::absolute(a), ec) == fs::weakly_canonical(fs::absolute(b), ec);
}

}  // namespace

const std::string& temporary_owner()
{
    static const std::string owner = [] {
        char host[256] = {};
        ::gethostname(host, sizeof(host) - 1);
        std::string name;
        for (const char* c = host; *c; ++c)
            name += std::isalnum(static_cast<unsigned char>(*c)) || *c == '.' || *c == '_'
                        ? *c
                        : '_';
        // "pid:[4026531836]": the namespace's inode, the same for every process in it.
        char link[64] = {};
        std::string ns = "0";
        if (::readlink("/proc/self/ns/pid", link, sizeof(link) - 1) > 0) {
            std::string text(link);
            size_t open = text.find('['), close = text.find(']');
            if (open != std::string::npos && close != std::string::npos)
                ns = text.substr(open + 1, close - open - 1);
        }
        return format("{}-{}", ns, name.empty() ? "host" : name);
    }();
    return owner;
}

bool check_output_path(const std::string& path, const std::vector<std::string>& inputs,
                       std::string& error)
{
    if (path.empty()) {
        error = "an output needs a file name";
        return false;
    }
    for (const auto& input : inputs)
        if (!input.empty() && same_file(path, input)) {
            error = format("{}: the output is also an input ({}): refusing to replace it; "
                           "write to another name", path, input);
            return false;
        }
    std::error_code ec;
    const fs::file_status status = fs::status(path, ec);
    if (fs::is_directory(status)) {
        error = format("{}: is a directory: -o needs a file name", path);
        return false;
    }
    fs::path dir = fs::path(path).parent_path();
    if (dir.empty())
        dir = ".";
    if (!fs::is_directory(dir, ec)) {
        error = format("{}: folder {} does not exist", path, dir.string());
        return false;
    }
    if (::access(dir.c_str(), W_OK | X_OK) != 0) {
        error = format("{}: cannot write in folder {} ({})", path, dir.string(),
                       std::strerror(errno));
        return false;
    }
    if (fs::exists(status) && ::access(path.c_str(), W_OK) != 0) {
        error = format("{}: exists and cannot be written ({}): not replacing it", path,
                       std::strerror(errno));
        return false;
    }
    // root may write anything: a file nobody may write is still not replaced (cp -i and
    // oiiotool's users expect a read-only golden image to stay).
    struct stat st;
    if (fs::exists(status) && ::stat(path.c_str(), &st) == 0 && (st.st_mode & 0222) == 0) {
        error = format("{}: exists and is read-only (mode {:04o}): not replacing it", path,
                       st.st_mode & 07777);
        return false;
    }
    return true;
}

bool check_compression(const std::string& compression, std::string& error)
{
    if (compression.empty())  // formats without compression (the heatmap's PNG)
        return true;
    static const std::vector<std::string> names = { "none", "rle", "zips", "zip", "piz",
                                                    "pxr24", "b44", "b44a", "dwaa", "dwab" };
    std::string name = compression, level;
    if (size_t colon = compression.find(':'); colon != std::string::npos) {
        name = compression.substr(0, colon);
        level = compression.substr(colon + 1);
    }
    bool leveled = name == "zip" || name == "zips" || name == "dwaa" || name == "dwab";
    bool ok = std::find(names.begin(), names.end(), name) != names.end()
              && (level.empty() || (leveled && Strutil::string_is_int(level)
                                    && Strutil::stoi(level) >= 0));
    if (!ok)
        error = format("compression={} is not one of {} (zip, zips, dwaa and dwab take :LEVEL)",
                       compression, Strutil::join(names, ", "));
    return ok;
}

void remove_temporary_outputs()
{
    for (auto& slot : g_temporaries)
        if (slot.state.load() == 2)
            ::unlink(slot.path);
}

namespace {

// What write_image and RowWriter tell about the values they write, channel by channel: NaN
// and Inf (no op makes them, so they came with the input, in channels no role reads), and,
// for half output, finite values beyond half's range, which are clamped to +-65504 (half
// would make them Inf).
struct ValueCounts {
    std::vector<size_t> nan, inf, clamped;

    /// Counts (and, to half, clamps) `pixels` interleaved pixels of nch channels.
    void inspect(float* values, size_t pixels, int nch, bool to_half)
    {
        nan.resize(nch, 0);
        inf.resize(nch, 0);
        clamped.resize(nch, 0);
        constexpr float kHalfMax = 65504.0f;
        for (size_t p = 0; p < pixels; ++p)
            for (int c = 0; c < nch; ++c) {
                float& v = values[p * nch + c];
                if (std::isnan(v))
                    ++nan[c];
                else if (std::isinf(v))
                    ++inf[c];
                else if (to_half && std::fabs(v) > kHalfMax) {
                    v = std::copysign(kHalfMax, v);
                    ++clamped[c];
                }
            }
    }

    void warn(const std::string& path, const std::vector<std::string>& names,
              std::vector<std::string>& warnings) const
    {
        for (size_t c = 0; c < nan.size(); ++c) {
            if (nan[c] || inf[c])
                warnings.push_back(format("{}: channel {} has {} NaN and {} Inf values, written "
                                          "as they came in (no stage reads it; --fixnan "
                                          "repairs)", path, names[c], nan[c], inf[c]));
            if (clamped[c])
                warnings.push_back(format("{}: channel {}: {} values beyond half's range "
                                          "clamped to +-65504 (datatype=float keeps them)",
                                          path, names[c], clamped[c]));
        }
    }
};

}  // namespace

namespace {

// What write_image and RowWriter write: the file's spec (its channels in `order` of the
// image's), and for a multi-part render (an EXR only) its parts.
struct OutputLayout {
    ImageSpec spec;
    std::vector<int> order;
    std::vector<Part> parts;
    std::vector<std::vector<std::string>> part_channels;  // original names, per part
};

bool output_layout(OutputLayout& layout, const ImageSpec& in_spec, const std::string& path,
                   const WriteOptions& options, std::string& error)
{
    if (!check_compression(options.compression, error)) {
        error = format("{}: {}", path, error);
        return false;
    }
    std::vector<std::string> inputs;
    for (const InputFile& file : merged_input_files(in_spec))
        inputs.push_back(file.path);
    if (!check_output_path(path, inputs, error))
        return false;
    std::vector<std::string> wanted = options.channels;
    if (wanted.empty())
        wanted = Strutil::splits(in_spec.get_string_attribute(kOutputChannelsAttribute), "\n");
    if (wanted.empty())
        wanted = in_spec.channelnames;
    for (const auto& name : wanted)
        if (in_spec.channelindex(name) < 0) {
            error = format("{}: cannot write channel '{}': not in the image; channels there: {}",
                           path, name, channel_list(in_spec));
            return false;
        }
    // A multi-part render goes back into its parts (an EXR only): each channel into the part
    // it came from, channels the stages added into the first; parts left empty are dropped.
    std::vector<Part>& parts = layout.parts;
    parts = parse_parts(in_spec.get_string_attribute(kPartsAttribute));
    if (parts.size() > 1 && Strutil::iends_with(path, ".exr")) {
        std::vector<std::vector<std::string>> grouped(parts.size());
        layout.part_channels.resize(parts.size());
        for (const auto& name : wanted) {
            size_t p = 0;
            std::string original = name;
            for (size_t q = 0; q < parts.size(); ++q)
                for (const auto& [merged, own] : parts[q].channels)
                    if (merged == name) {
                        p = q;
                        original = own;
                    }
            grouped[p].push_back(name);
            layout.part_channels[p].push_back(original);
        }
        wanted.clear();
        for (const auto& g : grouped)
            wanted.insert(wanted.end(), g.begin(), g.end());
    } else {
        parts.clear();
    }
    for (const auto& name : wanted)
        layout.order.push_back(in_spec.channelindex(name));
    ImageSpec& spec = layout.spec;
    spec = in_spec;
    spec.nchannels = int(wanted.size());
    spec.channelnames = wanted;
    for (const auto& name : { "mcdn:inputs", kOutputChannelsAttribute, kPartsAttribute,
                              kHalvesUnread, kDenoiserTilesAttribute })
        spec.erase_attribute(name);
    spec.set_format(options.datatype);
    spec.channelformats.clear();
    // Written in scanlines, as the stages make rows: a tiled or MIP-mapped input (Arnold's
    // and RenderMan's usual EXRs) gives a plain image of its level 0, as oiiotool's -o
    // without --tile does.
    spec.tile_width = spec.tile_height = 0;
    spec.tile_depth = 1;
    for (const char* name : { "openexr:levelmode", "openexr:roundingmode", "textureformat",
                              "wrapmodes" })
        spec.erase_attribute(name);
    spec.attribute("compression", options.compression);
    if (!options.software.empty()) {
        std::string software = spec.get_string_attribute("Software");
        if (!Strutil::ends_with(software, options.software))
            software += (software.empty() ? "" : "; ") + options.software;
        spec.attribute("Software", software);
    }
    if (!options.history.empty()) {
        std::string history = spec.get_string_attribute("Exif:ImageHistory");
        spec.attribute("Exif:ImageHistory",
                       (history.empty() ? "" : history + "\n") + options.history);
    }
    spec.alpha_channel = spec.channelindex("A");
    spec.z_channel     = spec.channelindex("Z");
    return true;
}

// A temporary beside `path` for it (`.NAME.mcdn-tmp-PID-N`): the temporaries a killed
// run left for the same path are removed first.
std::string temporary_for(const std::string& path)
{
    static std::atomic<int> counter { 0 };
    remove_stale_temporaries(path);
    return format("{}{}-{}-{}", temporary_prefix(path), ::getpid(), counter++,
                  temporary_owner());
}

// Renames the finished temporary over `path`; a file it replaces keeps its mode (a 0600
// output stays private).
bool put_in_place(const std::string& tmp, const std::string& path, std::string& error)
{
    struct stat st;
    if (::stat(path.c_str(), &st) == 0 && S_ISREG(st.st_mode))
        ::chmod(tmp.c_str(), st.st_mode & 07777);
    std::string rename_error;
    if (!Filesystem::rename(tmp, path, rename_error)) {
        error = format("{}: cannot rename temporary file into place: {}", path, rename_error);
        Filesystem::remove(tmp);
        return false;
    }
    return true;
}

}  // namespace

bool write_image(const ImageBuf& src, const std::string& path, const WriteOptions& options,
                 std::string& error, std::vector<std::string>* warnings)
{
    OutputLayout layout;
    if (!output_layout(layout, src.spec(), path, options, error))
        return false;
    // One part: written as a chain writes its bands, the channels gathered a chunk of rows
    // at a time (a whole copy first would be a frame of fresh pages).
    if (layout.parts.empty()) {
        RowWriter writer;
        return writer.open(src.spec(), path, options, error)
               && writer.write_rows(src, src.roi(), error) && writer.close(error, warnings);
    }
    const std::vector<int>& order = layout.order;
    ImageBuf out = OIIO::ImageBufAlgo::channels(src, int(order.size()), order);
    if (out.has_error()) {
        error = format("{}: {}", path, out.geterror());
        return false;
    }
    std::vector<std::string> found;
    if (out.spec().format == TypeDesc::FLOAT && out.localpixels()) {
        ValueCounts counts;
        counts.inspect(static_cast<float*>(out.localpixels()), out.spec().image_pixels(),
                       out.nchannels(), options.datatype == TypeDesc::HALF);
        counts.warn(path, out.spec().channelnames, found);
    }
    if (warnings)
        warnings->insert(warnings->end(), found.begin(), found.end());
    const ImageSpec& spec = layout.spec;
    const std::vector<Part>& parts = layout.parts;

    // Write beside the target, then rename: readers never see a half-written file. The
    // temporary's name says which output and which process it belongs to.
    auto output = ImageOutput::create(path);
    if (!output) {
        error = format("{}: cannot write this format: {}", path, one_line(OIIO::geterror()));
        return false;
    }
    const std::string tmp = temporary_for(path);
    TemporaryRegistration registration(tmp);
    std::vector<ImageSpec> specs;
    std::vector<int> first_channel;
    int first = 0;
    for (size_t p = 0; p < parts.size(); ++p) {
        const int n = int(layout.part_channels[p].size());
        if (n == 0)
            continue;
        ImageSpec part = spec;
        part.nchannels = n;
        part.channelnames = layout.part_channels[p];
        part.attribute("name", parts[p].name);
        part.attribute("oiio:subimagename", parts[p].name);
        part.alpha_channel = part.channelindex("A");
        part.z_channel = part.channelindex("Z");
        specs.push_back(part);
        first_channel.push_back(first);
        first += n;
    }
    const OIIO::stride_t pixel = OIIO::stride_t(out.nchannels()) * sizeof(float);
    const float* pixels = static_cast<const float*>(out.localpixels());
    bool ok = output->supports("multiimage")
              && output->open(tmp, int(specs.size()), specs.data());
    for (size_t p = 0; ok && p < specs.size(); ++p)
        ok = (p == 0 || output->open(tmp, specs[p], ImageOutput::AppendSubimage))
             && output->write_image(TypeDesc::FLOAT, pixels + first_channel[p], pixel,
                                    pixel * spec.width);
    ok = output->close() && ok;
    if (!ok) {
        error = format("{}: write failed: {}", path, one_line(output->geterror()));
        Filesystem::remove(tmp);
        return false;
    }
    return put_in_place(tmp, path, error);
}

struct RowWriter::State {
    std::string path, tmp;
    OutputLayout layout;
    std::unique_ptr<ImageOutput> output;
    std::unique_ptr<TemporaryRegistration> registration;
    bool to_half = false;
    int next_row = 0;
    ValueCounts counts;
    std::vector<float> rows;
};

RowWriter::RowWriter() = default;

RowWriter::~RowWriter()
{
    if (m && m->output) {
        m->output->close();
        Filesystem::remove(m->tmp);
    }
}

bool RowWriter::open(const ImageSpec& image, const std::string& path, const WriteOptions& options,
                     std::string& error)
{
    m = std::make_unique<State>();
    m->path = path;
    if (!output_layout(m->layout, image, path, options, error))
        return false;
    if (!m->layout.parts.empty()) {
        error = format("{}: a multi-part image is written whole (write_image), not in rows",
                       path);
        return false;
    }
    m->output = ImageOutput::create(path);
    if (!m->output) {
        error = format("{}: cannot write this format: {}", path, one_line(OIIO::geterror()));
        return false;
    }
    m->tmp = temporary_for(path);
    m->registration = std::make_unique<TemporaryRegistration>(m->tmp);
    if (!m->output->open(m->tmp, m->layout.spec)) {
        error = format("{}: write failed: {}", path, m->output->geterror());
        m->output.reset();
        Filesystem::remove(m->tmp);
        return false;
    }
    m->to_half = options.datatype == TypeDesc::HALF;
    m->next_row = image.y;
    return true;
}

bool RowWriter::write_rows(const ImageBuf& band, const ROI& own, std::string& error)
{
    const ImageSpec& spec = m->layout.spec;
    const int nch = spec.nchannels;
    if (!m->output || own.ybegin != m->next_row || own.xbegin != spec.x
        || own.width() != spec.width) {
        error = format("{}: rows {}-{} out of order (next: {})", m->path, own.ybegin, own.yend,
                       m->next_row);
        return false;
    }
    std::vector<int> from(nch);
    for (int c = 0; c < nch; ++c) {
        from[c] = band.spec().channelindex(spec.channelnames[c]);
        if (from[c] < 0) {
            error = format("{}: channel '{}' is not in the result", m->path, spec.channelnames[c]);
            return false;
        }
    }
    // The output's channels, pixel-interleaved and checked as write_image checks, a chunk of
    // rows at a time: the chunk is all the writer holds besides the band (a whole band's
    // copy would add a frame of the output's channels at the peak), about 16 MB of rows, in
    // multiples of 32 (zip's blocks are 16 rows, piz's and dwaa's 32; OpenEXR keeps a partly
    // filled block of dwab's 256 rows until the next call completes it).
    const size_t row_bytes = size_t(own.width()) * nch * sizeof(float);
    const int kChunkRows = std::clamp(int(((size_t(16) << 20) / std::max<size_t>(row_bytes, 1)
                                           + 31) / 32 * 32), 32, 256);
    const ImageSpec& in = band.spec();
    const float* pixels = float_frame_pixels(band);
    for (int y0 = own.ybegin; y0 < own.yend; y0 += kChunkRows) {
        ROI chunk = own;
        chunk.ybegin = y0;
        chunk.yend = std::min(own.yend, y0 + kChunkRows);
        const size_t npixels = size_t(chunk.width()) * chunk.height();
        m->rows.resize(npixels * nch);
        if (pixels) {
            // One pass over the rows (a channel at a time would stride through all of them
            // once per channel).
            const int bch = in.nchannels;
            tbb::parallel_for(tbb::blocked_range<int>(chunk.ybegin, chunk.yend),
                              [&](const tbb::blocked_range<int>& b) {
                for (int y = b.begin(); y != b.end(); ++y) {
                    const float* src = pixels + (size_t(y - in.y) * in.width
                                                 + size_t(chunk.xbegin - in.x)) * bch;
                    float* dst = m->rows.data() + size_t(y - chunk.ybegin) * chunk.width() * nch;
                    for (int x = 0; x < chunk.width(); ++x)
                        for (int c = 0; c < nch; ++c)
                            dst[size_t(x) * nch + c] = src[size_t(x) * bch + from[c]];
                }
            });
        } else {
            for (int c = 0; c < nch; ++c) {
                ROI one = chunk;
                one.chbegin = from[c];
                one.chend = from[c] + 1;
                if (!band.get_pixels(one, TypeDesc::FLOAT, m->rows.data() + c,
                                     OIIO::stride_t(nch * sizeof(float)))) {
                    error = format("{}: {}", m->path, band.geterror());
                    return false;
                }
            }
        }
        m->counts.inspect(m->rows.data(), npixels, nch, m->to_half);
        if (!m->output->write_scanlines(chunk.ybegin, chunk.yend, 0, TypeDesc::FLOAT,
                                        m->rows.data())) {
            error = format("{}: write failed: {}", m->path, one_line(m->output->geterror()));
            return false;
        }
    }
    m->next_row = own.yend;
    return true;
}

bool RowWriter::close(std::string& error, std::vector<std::string>* warnings)
{
    const ImageSpec& spec = m->layout.spec;
    if (!m->output || m->next_row != spec.y + spec.height) {
        error = format("{}: closed after row {} of {}", m->path, m->next_row,
                       spec.y + spec.height);
        return false;
    }
    const bool ok = m->output->close();
    const std::string output_error = ok ? std::string() : m->output->geterror();
    m->output.reset();
    if (!ok) {
        error = format("{}: write failed: {}", m->path, output_error);
        Filesystem::remove(m->tmp);
        return false;
    }
    if (warnings)
        m->counts.warn(m->path, spec.channelnames, *warnings);
    return put_in_place(m->tmp, m->path, error);
}

}  // namespace mcdn
