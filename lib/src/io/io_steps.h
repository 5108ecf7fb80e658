// What the files of io/ share: the merged buffer's bookkeeping attributes, pieces of the
// messages, and the steps one file takes for another.
#pragma once

#include <set>
#include <string>

#include <OpenImageIO/imagebuf.h>
#include <OpenImageIO/strutil.h>

#include "mcdn/io.h"

namespace mcdn {

// The parts of a multi-part render, kept in the merged buffer so that write_image writes
// the same parts: a line per part, its name then pairs of merged and original channel names,
// tab-separated.
constexpr const char* kPartsAttribute = "mcdn:parts";
// The pixel type each channel of the render (the mean inputs) had in its file, a line per
// channel, name and type tab-separated: write_image writes each so unless told otherwise.
constexpr const char* kInputTypesAttribute = "mcdn:input_types";
// Set when read_inputs read no half-buffer channel (InputSelection::halves false).
constexpr const char* kHalvesUnread = "mcdn:halves_unread";

// Same pixel window, whatever the channel counts.
inline bool same_window(const ROI& a, const ROI& b)
{
    return a.xbegin == b.xbegin && a.xend == b.xend && a.ybegin == b.ybegin && a.yend == b.yend;
}

inline std::string roi_text(const ROI& roi)
{
    return OIIO::Strutil::fmt::format("{}x{} at ({},{})", roi.width(), roi.height(), roi.xbegin,
                                      roi.ybegin);
}

// An OIIO error as one line of ours: it may hold several, one per problem it found.
inline std::string one_line(std::string text)
{
    while (!text.empty() && (text.back() == '\n' || text.back() == ' '))
        text.pop_back();
    return OIIO::Strutil::replace(text, "\n", "; ", true);
}

// Copies every channel of `src` into `dst` starting at channel `first`: dst's rows, which
// src holds (same columns, float) (read.cpp).
void copy_channels(ImageBuf& dst, int first, const ImageBuf& src);

// A file given as the variance or a half must supply that face of the colour: one that does
// not (a PNG renamed var.exr, a layer without Combined.B) would be ignored and the stages
// would run without it. Only the channel names are looked at; `halves` false skips the half
// files (validate.cpp).
bool check_color_faces(const ImageSpec& spec, const AovSet& aovs, bool halves, std::string& error);

// The variance and half-buffer channels `selection` keeps of a merged buffer's full list of
// names (`spec`, before any pixel is read) (selection.cpp).
std::set<std::string> selected_faces(const ImageSpec& spec, const InputSelection& selection,
                                     std::string& error);

// Holds `path` in a slot of the signal handler's (remove_temporary_outputs) while it exists
// on disk; no slot (all taken, or too long a path) only means a signal could not remove it:
// a later write for the same output will (temporaries.cpp).
class TemporaryRegistration {
public:
    explicit TemporaryRegistration(const std::string& path);
    ~TemporaryRegistration();
    TemporaryRegistration(const TemporaryRegistration&) = delete;
    TemporaryRegistration& operator=(const TemporaryRegistration&) = delete;

private:
    void* m_slot = nullptr;
};

// A temporary beside `path` for it (`.NAME.mcdn-tmp-PID-N-OWNER`): the temporaries a dead
// writer left for the same path are removed first (temporaries.cpp).
std::string temporary_for(const std::string& path);
// Renames the finished temporary over `path`; a file it replaces keeps its mode (a 0600
// output stays private). The temporary is removed when that fails (temporaries.cpp).
bool put_in_place(const std::string& tmp, const std::string& path, std::string& error);

}  // namespace mcdn
