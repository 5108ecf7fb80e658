// What a file holds, from its headers alone (layout.cpp): read before any pixel, so that every
// name and window is checked first, and the reader of its pixels chosen.
#pragma once

#include <memory>
#include <string>
#include <vector>

#include <OpenImageIO/imageio.h>

namespace mcdn {

using OIIO::ImageSpec;

// A file's channels as read_image names them, from its header alone: each part's float spec
// and, in order, every part's channels (part_qualified).
struct FileLayout {
    std::string path;
    std::vector<ImageSpec> parts;
    std::vector<std::string> names;
    std::vector<int> subimages;  // each part's subimage in the file
    bool exr = false;
    std::vector<OIIO::TypeDesc> types;  // each of `names`' pixel type in the file
    // Each part's rows per block as OpenEXR's core reads them (core_block_rows): set where
    // every part is one the core may read, else empty (the C++ library reads the file).
    std::vector<int> core_rows;

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

/// The file's layout (`part`: -i:part's comma-separated names, empty for every part); false
/// with a one-line `error` naming the file.
bool read_layout(FileLayout& layout, const std::string& path, const std::string& part,
                 std::string& error);

/// The parts of a multi-part render as kPartsAttribute holds them (io_steps.h).
std::string parts_text(const FileLayout& layout);

/// True when OpenEXR's C core reads the file's pixels (FileLayout::core_rows).
bool core_reads(const FileLayout& layout);

/// The file opened for its pixels, by the reader core_reads chose.
std::unique_ptr<OIIO::ImageInput> open_for_pixels(const FileLayout& layout);

}  // namespace mcdn
