// The weights file (format in nn/nn.h): read, write, describe. Every integer and float is
// little-endian; this file assumes a little-endian host (x86-64, AArch64) and says so below.
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <iterator>
#include <set>
#include <sstream>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include "mcdn/io.h"
#include "mcdn/version.h"
#include "nn/nn.h"

namespace mcdn {
namespace nn {

static_assert(sizeof(float) == 4, "the weights format stores IEEE float32");

namespace {

constexpr char weights_magic[8] = { 'M', 'C', 'D', 'N', 'N', 'W', 'T', 'S' };
// Bounds that no real network reaches; they turn a corrupt count into an error, not a
// multi-gigabyte allocation.
constexpr uint32_t max_rank = 8;
constexpr uint32_t max_name_bytes = 1 << 16;
constexpr uint64_t max_file_bytes = uint64_t(1) << 31;

bool host_is_little_endian()
{
    const uint32_t one = 1;
    unsigned char first;
    std::memcpy(&first, &one, 1);
    return first == 1;
}

/// Reads the file's bytes front to back; every read says what it was reading so a
/// truncated file is reported as "truncated in tensor 'x'".
class ByteReader {
public:
    ByteReader(const std::string& bytes) : bytes_(bytes) { }
    size_t remaining() const { return bytes_.size() - pos_; }
    size_t position() const { return pos_; }

    bool read(void* dst, size_t n)
    {
        if (remaining() < n)
            return false;
        std::memcpy(dst, bytes_.data() + pos_, n);
        pos_ += n;
        return true;
    }
    bool read_u32(uint32_t& value) { return read(&value, 4); }
    bool read_string(std::string& s, uint32_t n)
    {
        if (remaining() < n)
            return false;
        s.assign(bytes_.data() + pos_, n);
        pos_ += n;
        return true;
    }

private:
    const std::string& bytes_;
    size_t pos_ = 0;
};

void append(std::string& out, const void* data, size_t n)
{
    out.append(static_cast<const char*>(data), n);
}
void append_u32(std::string& out, uint32_t value)
{
    append(out, &value, 4);
}

}  // namespace

Tensor::Tensor(int height_, int width_, int channels_, float fill)
    : height(height_), width(width_), channels(channels_),
      data(size_t(height_) * width_ * channels_, fill)
{ }

const NamedTensor* Weights::find(const std::string& name) const
{
    for (const NamedTensor& t : tensors)
        if (t.name == name)
            return &t;
    return nullptr;
}

std::string shape_string(const std::vector<int>& shape)
{
    std::string s = "[";
    for (size_t i = 0; i < shape.size(); ++i)
        s += (i ? "," : "") + std::to_string(shape[i]);
    return s + "]";
}

bool read_weights(const std::string& path, Weights& weights, std::string& error)
{
    weights = Weights();
    weights.path = path;
    if (!host_is_little_endian()) {
        error = path + ": weights files are little-endian and this host is not (unsupported)";
        return false;
    }
    // A regular file, its magic checked before its size is trusted and read: /dev/zero or
    // /proc/self/mem must be an error, not gigabytes read or an exception.
    if (!check_input_file(path, error))
        return false;
    const std::string not_weights =
        path + ": not a mcdenoise weights file (it does not start with \"MCDNNWTS\")";
    std::string bytes;
    {
        const int fd = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
        struct stat st;
        if (fd < 0 || ::fstat(fd, &st) != 0) {
            error = path + ": cannot open the weights file (" + std::strerror(errno) + ")";
            if (fd >= 0)
                ::close(fd);
            return false;
        }
        char magic[8] = {};
        const bool is_weights =
            ::read(fd, magic, 8) == 8 && std::memcmp(magic, weights_magic, 8) == 0;
        if (!is_weights || uint64_t(st.st_size) > max_file_bytes) {
            ::close(fd);
            error = is_weights ? path + ": " + std::to_string(st.st_size)
                                     + " bytes, more than any network's weights (corrupt?)"
                               : not_weights;
            return false;
        }
        bytes.assign(magic, 8);
        bytes.resize(size_t(st.st_size));
        size_t done = 8;
        while (done < bytes.size()) {
            const ssize_t n = ::read(fd, &bytes[done], bytes.size() - done);
            if (n <= 0)
                break;
            done += size_t(n);
        }
        ::close(fd);
        if (done != bytes.size()) {
            error = path + ": cannot read the weights file (it changed while read?)";
            return false;
        }
    }
    ByteReader in(bytes);

    char magic[8];
    if (!in.read(magic, 8) || std::memcmp(magic, weights_magic, 8) != 0) {
        error = not_weights;
        return false;
    }
    uint32_t metadata_bytes = 0;
    if (!in.read_u32(weights.version)) {
        error = path + ": truncated in the header";
        return false;
    }
    if (weights.version != weights_format_version) {
        error = path + ": weights format version " + std::to_string(weights.version)
                + ", this build reads version " + std::to_string(weights_format_version)
                + " (re-export it with training/common/weights.py)";
        return false;
    }
    uint32_t count = 0;
    if (!in.read_u32(metadata_bytes) || !in.read_string(weights.metadata, metadata_bytes)
        || !in.read_u32(count)) {
        error = path + ": truncated in the header";
        return false;
    }

    std::set<std::string> names;
    for (uint32_t t = 0; t < count; ++t) {
        NamedTensor tensor;
        uint32_t name_bytes = 0, rank = 0;
        const std::string which =
            "tensor " + std::to_string(t + 1) + " of " + std::to_string(count);
        if (!in.read_u32(name_bytes) || name_bytes > max_name_bytes
            || !in.read_string(tensor.name, name_bytes)) {
            error = path + ": truncated or corrupt in the name of " + which;
            return false;
        }
        const std::string quoted = "tensor '" + tensor.name + "'";
        if (!names.insert(tensor.name).second) {
            error = path + ": " + quoted + " appears twice";
            return false;
        }
        if (!in.read_u32(rank) || rank > max_rank) {
            error = path + ": truncated or corrupt in the rank of " + quoted;
            return false;
        }
        uint64_t elements = 1;
        for (uint32_t d = 0; d < rank; ++d) {
            uint32_t dim = 0;
            if (!in.read_u32(dim) || dim == 0 || dim > (1u << 30)) {
                error = path + ": truncated or corrupt in the shape of " + quoted;
                return false;
            }
            tensor.shape.push_back(int(dim));
            elements *= dim;
        }
        // Check the size before allocating: a truncated file must not cost gigabytes.
        if (elements * 4 > in.remaining()) {
            error = path + ": truncated in the data of " + quoted + " " + shape_string(tensor.shape)
                    + " (" + std::to_string(elements * 4) + " bytes needed, "
                    + std::to_string(in.remaining()) + " left)";
            return false;
        }
        tensor.values.resize(elements);
        in.read(tensor.values.data(), elements * 4);
        weights.tensors.push_back(std::move(tensor));
    }
    if (in.remaining() != 0) {
        error = path + ": " + std::to_string(in.remaining())
                + " unexpected bytes after the last tensor (corrupt file?)";
        return false;
    }
    return true;
}

bool write_weights(const std::string& path, const Weights& weights, std::string& error)
{
    std::string out;
    append(out, weights_magic, 8);
    append_u32(out, weights_format_version);
    append_u32(out, uint32_t(weights.metadata.size()));
    out += weights.metadata;
    append_u32(out, uint32_t(weights.tensors.size()));
    for (const NamedTensor& t : weights.tensors) {
        size_t elements = 1;
        for (int d : t.shape)
            elements *= size_t(d);
        if (elements != t.values.size()) {
            error = path + ": tensor '" + t.name + "' has shape " + shape_string(t.shape) + " but "
                    + std::to_string(t.values.size()) + " values";
            return false;
        }
        append_u32(out, uint32_t(t.name.size()));
        out += t.name;
        append_u32(out, uint32_t(t.shape.size()));
        for (int d : t.shape)
            append_u32(out, uint32_t(d));
        append(out, t.values.data(), t.values.size() * 4);
    }
    std::ofstream file(path, std::ios::binary | std::ios::trunc);
    if (!file || !file.write(out.data(), std::streamsize(out.size())) || !file.flush()) {
        error = path + ": cannot write the weights file (" + std::strerror(errno) + ")";
        return false;
    }
    return true;
}

std::string describe(const Weights& weights)
{
    std::ostringstream s;
    size_t parameters = 0;
    for (const NamedTensor& t : weights.tensors)
        parameters += t.values.size();
    s << weights.path << ": weights format version " << weights.version << ", "
      << weights.tensors.size() << " tensors, " << parameters << " parameters\n";
    s << "metadata: " << (weights.metadata.empty() ? "(none)" : weights.metadata) << "\n";
    for (const NamedTensor& t : weights.tensors)
        s << "  " << t.name << " " << shape_string(t.shape) << "\n";
    return s.str();
}

std::string model_file(const std::string& name)
{
    return install_paths().models_dir + "/" + name;
}

}  // namespace nn
}  // namespace mcdn
