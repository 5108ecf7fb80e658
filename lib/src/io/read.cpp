// Reading renders into one merged float buffer (mcdn/io.h): each file's layout from its
// headers, then its pixels straight into the merged frame, a band of rows at a time.
#include "mcdn/io.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <set>

#include <sys/stat.h>
#include <unistd.h>

#include <OpenEXR/openexr.h>
#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/op_prepare.h"
#include "io/io_steps.h"
#include "io/layout.h"

namespace mcdn {

using OIIO::ImageInput;
using OIIO::TypeDesc;
namespace Filesystem = OIIO::Filesystem;
namespace Strutil = OIIO::Strutil;
using Strutil::fmt::format;

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

namespace {

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
        error = format("{}: cannot read pixels (truncated or corrupt, or out of memory?): {}",
                       layout.path, one_line(in.geterror()));
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
        const int aligned = tiled ? part.tile_height : core ? layout.core_rows[s] : 1;
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
            const bool read =
                tiled ? in.read_tiles(layout.subimages[s], 0, part.x, part.x + part.width, y, end,
                                      part.z, part.z + std::max(part.depth, 1), 0, n,
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

// One input's layout. A seed set and a Tungsten buffer directory are read whole, into
// `whole` (their faces exist only once combined); `own` is how many of a seed set's channels
// are the render's own (the faces made from them are not).
bool input_layout(FileLayout& layout, ImageBuf& whole, size_t& own, const InputFile& input,
                  std::string& error)
{
    const bool is_dir = Filesystem::is_directory(input.path);
    if (is_dir && input.kind != InputKind::Mean) {
        error = format("{}: a Tungsten buffer directory holds every face itself; give it "
                       "as a plain -i",
                       input.path);
        return false;
    }
    if (!input.seeds.empty()) {
        FileLayout seed;
        if (!input.part.empty()) {
            error = format("{}: -i:part does not apply to seeds: each is read whole", input.path);
            return false;
        }
        if (!read_layout(seed, input.seeds[0], "", error))
            return false;
        if (!combine_seeds(whole, input.seeds)) {
            error = whole.geterror();
            return false;
        }
        const ImageSpec& spec = whole.spec();
        std::vector<TypeDesc> types = seed.types;
        types.resize(spec.nchannels, TypeDesc::FLOAT);
        layout = { input.path, { spec }, spec.channelnames, { 0 }, false, types, {} };
        own = seed.names.size();
        return true;
    }
    if (is_dir) {
        if (!read_tungsten_directory(whole, input.path)) {
            error = whole.geterror();
            return false;
        }
        const ImageSpec& spec = whole.spec();
        layout = { input.path, { spec }, spec.channelnames,
                   { 0 },      false,    std::vector<TypeDesc>(spec.nchannels, TypeDesc::FLOAT),
                   {} };
        return true;
    }
    return read_layout(layout, input.path, input.part, error);
}

/// An OpenEXR file's headers parse with OpenEXR's own C core, which checks each attribute's
/// size against the file: the C++ library OIIO reads with allocates what an attribute claims
/// before it reads it, so a damaged 1 KB file could make it fill gigabytes (a string of 1.9
/// GB, first or later among the attributes; a tiled file without its tiles, whose channel list
/// then reads past the header: all found by the fuzz target) before it says the file ends
/// early. Other formats: true.
bool exr_headers_fit(const std::string& path, std::string& error)
{
    std::unique_ptr<FILE, int (*)(FILE*)> f(std::fopen(path.c_str(), "rb"), &std::fclose);
    unsigned char magic[4];
    if (!f || std::fread(magic, 1, 4, f.get()) != 4 || magic[0] != 0x76 || magic[1] != 0x2f
        || magic[2] != 0x31 || magic[3] != 0x01)
        return true;  // not OpenEXR (or unreadable: OIIO says)
    f.reset();
    // The first message, and whether any said an attribute's size does not fit: the core
    // skips such an attribute and goes on (exr_start_read succeeds), but OpenEXR's C++
    // library, which OIIO reads with, allocates the size it claims.
    struct Said {
        std::string message;
        bool size_mismatch = false;
    } said;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.user_data = &said;
    init.error_handler_fn = [](exr_const_context_t exr, exr_result_t code, const char* text) {
        void* user = nullptr;
        if (exr_get_user_data(exr, &user) != EXR_ERR_SUCCESS || !user)
            return;
        Said& s = *static_cast<Said*>(user);
        s.size_mismatch |= code == EXR_ERR_ATTR_SIZE_MISMATCH;
        if (text && s.message.empty())
            s.message = text;  // the first: the cause
    };
    exr_context_t exr = nullptr;
    const exr_result_t parsed = exr_start_read(&exr, path.c_str(), &init);
    exr_finish(&exr);
    if (parsed == EXR_ERR_SUCCESS && !said.size_mismatch)
        return true;
    const std::string& message = said.message;
    error = format("{}: a damaged OpenEXR header: {}", path,
                   message.empty() ? std::string(exr_get_default_error_message(parsed))
                                   : one_line(message));
    return false;
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
    return exr_headers_fit(path, error);
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

bool read_inputs(ImageBuf& dst, const std::vector<InputFile>& inputs)
{
    return read_inputs(dst, inputs, InputSelection());
}

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
    std::vector<std::string> names, provenance, output_channels, input_types;
    std::map<std::string, std::string> channel_file;
    // How many of each file's channels are the render's own (a seed set's faces are not).
    std::vector<size_t> own(inputs.size(), std::numeric_limits<size_t>::max());
    for (size_t i = 0; i < inputs.size(); ++i) {
        const InputFile& input = inputs[i];
        if (!input_layout(layouts[i], directories[i], own[i], input, error))
            return false;
        const ROI window = layouts[i].parts[0].roi(), first_window = layouts[0].parts[0].roi();
        if (!same_window(window, first_window)) {
            error = format("{}: data window {} differs from {}'s {}", input.path, roi_text(window),
                           inputs[0].path, roi_text(first_window));
            return false;
        }
        for (size_t c = 0; c < layouts[i].names.size(); ++c) {
            const std::string& ch = layouts[i].names[c];
            std::string name = input_kind_prefix(input.kind) + ch;
            if (channel_file.count(name)) {
                error = format("{}: channel '{}' is also in {}; give each input once, with "
                               "-i:as=variance|halfA|halfB for the other faces",
                               input.path, name, channel_file[name]);
                return false;
            }
            channel_file[name] = input.path;
            names.push_back(name);
            // A seed set's faces are made here, not the render's: -o writes its means.
            if (input.kind == InputKind::Mean && c < own[i]) {
                output_channels.push_back(name);
                if (c < layouts[i].types.size())
                    input_types.push_back(name + "\t" + layouts[i].types[c].c_str());
            }
        }
        for (const std::string& path :
             input.seeds.empty() ? std::vector<std::string> { input.path } : input.seeds)
            provenance.push_back(format("{}={}", input_kind_name(input.kind), path));
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
        all.attribute(kInputsAttribute, Strutil::join(provenance, "\n"));
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
    spec.attribute(kInputsAttribute, Strutil::join(provenance, "\n"));
    if (selection.only_roles && !selection.halves)
        spec.attribute(kHalvesUnread, 1);
    // A multi-part render is written back with the same parts (write_image).
    if (layouts[meta_from].parts.size() > 1)
        spec.attribute(kPartsAttribute, parts_text(layouts[meta_from]));
    spec.attribute(kOutputChannelsAttribute, Strutil::join(output_channels, "\n"));
    spec.attribute(kInputTypesAttribute, Strutil::join(input_types, "\n"));
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
        error = format("InputRows::read: rows [{}, {}) outside the frame's [{}, {})", ybegin, yend,
                       m_spec.y, m_spec.y + m_spec.height);
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
            error = format("{}: cannot read: {}", f.layouts[i].path, one_line(OIIO::geterror()));
            return false;
        }
        const ImageSpec& part = f.layouts[i].parts[0];
        const ImageSpec& now = in->spec(f.layouts[i].subimages[0]);
        if (now.width != part.width || now.height != part.height || now.x != part.x
            || now.y != part.y || now.channelnames != part.channelnames) {
            error = format("{}: the file changed while it was read (it is now {}x{}, {} "
                           "channel(s))",
                           f.layouts[i].path, now.width, now.height, now.nchannels);
            return false;
        }
        if (!read_pixels_into(out, first, f.layouts[i], *in, f.keep[i], ybegin, yend, error))
            return false;
    }
    dst = std::move(out);
    return true;
}

bool gives_variance(const std::vector<InputFile>& inputs)
{
    return std::any_of(inputs.begin(), inputs.end(), [](const InputFile& f) {
        return f.kind == InputKind::Variance || !f.seeds.empty();
    });
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

}  // namespace mcdn
