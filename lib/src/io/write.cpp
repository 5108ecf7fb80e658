// Writing results (mcdn/io.h write_image, RowWriter): the file's layout from the merged
// buffer (its parts, channels and metadata), through a temporary beside the output renamed
// into place, temporaries of dead writers removed.
#include "mcdn/io.h"

#include <algorithm>
#include <map>
#include <atomic>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>

#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <OpenImageIO/filesystem.h>
#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/imageio.h>
#include <OpenImageIO/strutil.h>

#include "core/attributes.h"
#include "core/planar.h"
#include "io/io_steps.h"

namespace mcdn {

using OIIO::ImageOutput;
using OIIO::TypeDesc;
namespace Filesystem = OIIO::Filesystem;
namespace Strutil = OIIO::Strutil;
using Strutil::fmt::format;

namespace {

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

namespace fs = std::filesystem;

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
                           "write to another name",
                           path, input);
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
    // A folder that does not exist yet is made as the file is written (temporary_for): the
    // nearest one that exists must be a folder we may write in.
    while (!fs::exists(dir, ec)) {
        const fs::path up = dir.parent_path();
        if (up == dir)
            break;
        dir = up.empty() ? fs::path(".") : up;
    }
    if (!fs::is_directory(dir, ec)) {
        error = format("{}: {} is not a folder", path, dir.string());
        return false;
    }
    if (::access(dir.c_str(), W_OK | X_OK) != 0) {
        error =
            format("{}: cannot write in folder {} ({})", path, dir.string(), std::strerror(errno));
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
    static const std::vector<std::string> names = { "none",  "rle", "zips", "zip",  "piz",
                                                    "pxr24", "b44", "b44a", "dwaa", "dwab" };
    std::string name = compression, level;
    if (size_t colon = compression.find(':'); colon != std::string::npos) {
        name = compression.substr(0, colon);
        level = compression.substr(colon + 1);
    }
    bool leveled = name == "zip" || name == "zips" || name == "dwaa" || name == "dwab";
    bool ok = std::find(names.begin(), names.end(), name) != names.end()
              && (level.empty()
                  || (leveled && Strutil::string_is_int(level) && Strutil::stoi(level) >= 0));
    if (!ok)
        error = format("compression={} is not one of {} (zip, zips, dwaa and dwab take :LEVEL)",
                       compression, Strutil::join(names, ", "));
    return ok;
}

std::vector<TypeDesc> written_types(const ImageSpec& image,
                                    const std::vector<std::string>& channels, TypeDesc datatype)
{
    std::map<std::string, TypeDesc> input_types;
    for (const auto& line : Strutil::splits(image.get_string_attribute(kInputTypesAttribute), "\n"))
        if (const auto fields = Strutil::splits(line, "\t"); fields.size() == 2)
            input_types[fields[0]] = TypeDesc(fields[1]);
    std::vector<TypeDesc> types;
    for (const auto& name : channels) {
        TypeDesc type = datatype;
        if (type == TypeDesc::UNKNOWN) {
            const auto found = input_types.find(name);
            type = found != input_types.end()
                           && (found->second == TypeDesc::HALF || found->second == TypeDesc::UINT)
                       ? found->second
                       : TypeDesc::FLOAT;
        }
        types.push_back(type);
    }
    return types;
}

void set_channel_types(ImageSpec& spec, const std::vector<TypeDesc>& types)
{
    const bool one_type =
        std::all_of(types.begin(), types.end(), [&](TypeDesc t) { return t == types.front(); });
    spec.set_format(types.empty() || !one_type ? TypeDesc::FLOAT : types.front());
    spec.channelformats.clear();
    if (!one_type)
        spec.channelformats = types;
}

namespace {

// What write_image and RowWriter tell about the values they write, channel by channel: NaN
// and Inf (no op makes them, so they came with the input, in channels no role reads), and,
// for half output, finite values beyond half's range, which are clamped to +-65504 (half
// would make them Inf).
struct ValueCounts {
    std::vector<size_t> nan, inf, clamped;

    /// Counts (and, in the channels written as half, clamps) `pixels` interleaved pixels of
    /// nch channels.
    void inspect(float* values, size_t pixels, int nch, const std::vector<bool>& to_half)
    {
        nan.resize(nch, 0);
        inf.resize(nch, 0);
        clamped.resize(nch, 0);
        for (size_t p = 0; p < pixels; ++p)
            for (int c = 0; c < nch; ++c) {
                float& v = values[p * nch + c];
                if (std::isnan(v))
                    ++nan[c];
                else if (std::isinf(v))
                    ++inf[c];
                else if (to_half[c] && std::fabs(v) > kHalfMax) {
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
                                          "repairs)",
                                          path, names[c], nan[c], inf[c]));
            if (clamped[c])
                warnings.push_back(format("{}: channel {}: {} values beyond half's range "
                                          "clamped to +-65504 (datatype=float keeps them)",
                                          path, names[c], clamped[c]));
        }
    }
};

// What write_image and RowWriter write: the file's spec (its channels in `order` of the
// image's), and for a multi-part render (an EXR only) its parts.
struct OutputLayout {
    ImageSpec spec;
    std::vector<bool> half;  // per written channel: written as half
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
    for (const auto& name : { kInputsAttribute, kOutputChannelsAttribute, kPartsAttribute,
                              kHalvesUnread, kDenoiserTilesAttribute, kInputTypesAttribute })
        spec.erase_attribute(name);
    const std::vector<TypeDesc> types = written_types(in_spec, wanted, options.datatype);
    for (TypeDesc type : types)
        layout.half.push_back(type == TypeDesc::HALF);
    set_channel_types(spec, types);
    // Written in scanlines, as the stages make rows: a tiled or MIP-mapped input (Arnold's
    // and RenderMan's usual EXRs) gives a plain image of its level 0, as oiiotool's -o
    // without --tile does.
    spec.tile_width = spec.tile_height = 0;
    spec.tile_depth = 1;
    for (const char* name :
         { "openexr:levelmode", "openexr:roundingmode", "textureformat", "wrapmodes" })
        spec.erase_attribute(name);
    // The render's own compression unless asked for another (one OpenEXR does not have, a
    // PNG's, gives zip).
    std::string compression = options.compression;
    if (compression.empty()) {
        std::string unused;
        compression = in_spec.get_string_attribute("compression");
        if (compression.empty() || !check_compression(compression, unused))
            compression = "zip";
    }
    spec.attribute("compression", compression);
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
    spec.z_channel = spec.channelindex("Z");
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
                       out.nchannels(), layout.half);
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
        if (!spec.channelformats.empty())
            part.channelformats.assign(spec.channelformats.begin() + first,
                                       spec.channelformats.begin() + first + n);
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
    bool ok = output->supports("multiimage") && output->open(tmp, int(specs.size()), specs.data());
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
    std::vector<bool> to_half;  // per channel
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
        error = format("{}: a multi-part image is written whole (write_image), not in rows", path);
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
    m->to_half = m->layout.half;
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
    const int kChunkRows = std::clamp(
        int(((size_t(16) << 20) / std::max<size_t>(row_bytes, 1) + 31) / 32 * 32), 32, 256);
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
            tbb::parallel_for(
                tbb::blocked_range<int>(chunk.ybegin, chunk.yend),
                [&](const tbb::blocked_range<int>& b) {
                    for (int y = b.begin(); y != b.end(); ++y) {
                        const float* src =
                            pixels
                            + (size_t(y - in.y) * in.width + size_t(chunk.xbegin - in.x)) * bch;
                        float* dst =
                            m->rows.data() + size_t(y - chunk.ybegin) * chunk.width() * nch;
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
        error = format("{}: closed after row {} of {}", m->path, m->next_row, spec.y + spec.height);
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
