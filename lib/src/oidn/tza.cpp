// OIDN's tensor archives (oidn_steps.h read_tza): the layout read field by field, every
// offset and size checked against the file before it is used.
#include <cstring>
#include <fstream>
#include <iterator>

#include <Imath/half.h>
#include <OpenImageIO/strutil.h>

#include "oidn/oidn_steps.h"

namespace mcdn {
namespace oidn_net {

using OIIO::Strutil::fmt::format;

namespace {

constexpr uint16_t kMagic = 0x41D7;
constexpr uint8_t kMajorVersion = 2;

// Little-endian fields out of the file's bytes; the first read past the end fails them all.
class Fields {
public:
    explicit Fields(const std::vector<unsigned char>& bytes) : m_bytes(bytes) { }
    bool ok() const { return m_ok; }
    void seek(uint64_t at)
    {
        m_ok = m_ok && at <= m_bytes.size();
        m_at = m_ok ? size_t(at) : m_at;
    }
    uint64_t unsigned_int(int size)
    {
        uint64_t value = 0;
        if (!(m_ok = m_ok && m_bytes.size() - m_at >= size_t(size)))
            return 0;
        for (int i = size - 1; i >= 0; --i)
            value = value << 8 | m_bytes[m_at + size_t(i)];
        m_at += size_t(size);
        return value;
    }
    std::string text(size_t size)
    {
        if (!(m_ok = m_ok && m_bytes.size() - m_at >= size))
            return {};
        std::string value(reinterpret_cast<const char*>(m_bytes.data() + m_at), size);
        m_at += size;
        return value;
    }

private:
    const std::vector<unsigned char>& m_bytes;
    size_t m_at = 0;
    bool m_ok = true;
};

}  // namespace

bool read_tza(const std::string& path, nn::Weights& weights, std::string& error)
{
    std::ifstream file(path, std::ios::binary);
    if (!file) {
        error = format("{}: cannot be read", path);
        return false;
    }
    const std::vector<unsigned char> bytes((std::istreambuf_iterator<char>(file)),
                                           std::istreambuf_iterator<char>());
    Fields in(bytes);
    const uint64_t magic = in.unsigned_int(2), major = in.unsigned_int(1);
    in.unsigned_int(1);  // minor version: additions a reader of major 2 may ignore
    const uint64_t table = in.unsigned_int(8);
    if (!in.ok() || magic != kMagic || major != kMajorVersion) {
        error =
            format("{}: not an OIDN tensor archive (.tza) of version {}", path, int(kMajorVersion));
        return false;
    }
    in.seek(table);
    const uint64_t count = in.unsigned_int(4);
    weights = nn::Weights();
    weights.path = path;
    for (uint64_t t = 0; t < count && in.ok(); ++t) {
        nn::NamedTensor tensor;
        tensor.name = in.text(in.unsigned_int(2));
        const uint64_t rank = in.unsigned_int(1);
        size_t elements = 1;
        for (uint64_t d = 0; d < rank; ++d) {
            tensor.shape.push_back(int(in.unsigned_int(4)));
            elements *= size_t(std::max(tensor.shape.back(), 0));
        }
        in.text(rank);  // the layout: OIHW for convolutions, as the engine takes them
        const std::string type = in.text(1);
        const uint64_t data = in.unsigned_int(8);
        const size_t size = type == "h" ? 2 : 4;
        if (!in.ok() || (type != "h" && type != "f") || rank > 4 || elements > (1u << 28)
            || data > bytes.size() || (bytes.size() - data) / size < elements) {
            error = format("{}: tensor {} ('{}') is truncated or of an unknown type", path, t,
                           tensor.name);
            return false;
        }
        tensor.values.resize(elements);
        const unsigned char* p = bytes.data() + data;
        for (size_t i = 0; i < elements; ++i, p += size) {
            if (size == 2) {
                Imath::half h;
                h.setBits(uint16_t(p[0] | p[1] << 8));
                tensor.values[i] = float(h);
            } else {
                uint32_t bits = uint32_t(p[0]) | uint32_t(p[1]) << 8 | uint32_t(p[2]) << 16
                                | uint32_t(p[3]) << 24;
                std::memcpy(&tensor.values[i], &bits, 4);
            }
        }
        weights.tensors.push_back(std::move(tensor));
    }
    if (!in.ok() || weights.tensors.empty()) {
        error = format("{}: the tensor table is truncated", path);
        return false;
    }
    return true;
}

}  // namespace oidn_net
}  // namespace mcdn
