#include "ops/motion.h"

#include <cmath>

#include <OpenImageIO/strutil.h>

#include "aov/presets.h"
#include "mcdn/color.h"

namespace mcdn {

bool read_motion(FrameMotion& motion, const OIIO::ImageBuf& frame, const AovSet& aovs,
                 std::string& error)
{
    if (!aovs.has(Role::Motion)) {
        error = "no motion vectors (role motion: Blender's Vector pass, RenderMan's backward "
                "and forward, or --aov motion=X,Y,Z,W)";
        return false;
    }
    const std::vector<int>& c = aovs.channels(Role::Motion);
    const std::array<float, 4> sign = preset_motion_signs(aovs.preset());
    Plane* planes[4] = { &motion.to_previous[0], &motion.to_previous[1], &motion.to_next[0],
                         &motion.to_next[1] };
    for (int k = 0; k < 4; ++k) {
        *planes[k] = read_plane(frame, c[size_t(k)]);
        for (float& v : planes[k]->px)
            v = std::isfinite(v) ? sign[size_t(k)] * v : 0.0f;  // no motion known: it stays
    }
    return true;
}

FrameAlignment align_frames(const std::vector<const FrameMotion*>& steps, bool backwards,
                            int origin_x, int origin_y, int width, int height)
{
    FrameAlignment a;
    if (steps.empty())
        return a;
    const Plane& first = steps[0]->to_previous[0];
    a.width = first.width;
    a.height = first.height;
    a.source.resize(size_t(a.width) * a.height);
    for (int y = 0; y < a.height; ++y)
        for (int x = 0; x < a.width; ++x) {
            double px = x + origin_x, py = y + origin_y;
            size_t at = size_t(y) * a.width + x;  // in steps[0]'s pixels, then the frames'
            int64_t source = -1;
            for (size_t k = 0; k < steps.size(); ++k) {
                const Plane* d = backwards ? steps[k]->to_previous : steps[k]->to_next;
                px += d[0].px[at];
                py += d[1].px[at];
                const long ix = std::lround(px), iy = std::lround(py);
                if (ix < 0 || iy < 0 || ix >= width || iy >= height) {
                    source = -1;
                    break;
                }
                source = int64_t(iy) * width + ix;
                at = size_t(source);
            }
            a.source[size_t(y) * a.width + x] = source;
        }
    return a;
}

Plane warp(const Plane& plane, const FrameAlignment& alignment, float outside)
{
    Plane out(alignment.width, alignment.height);
    for (size_t i = 0; i < out.size(); ++i) {
        const int64_t s = alignment.source[i];
        out.px[i] = s >= 0 ? plane.px[size_t(s)] : outside;
    }
    return out;
}

std::string AlignedFrame::error(const std::string& why) const
{
    return OIIO::Strutil::fmt::format("cross-frame: frame {:+d} ({}): {}", offset, name, why);
}

namespace {

/// src's rows lie inside the frame's data window, which has src's columns.
bool holds_rows_of(const ImageSpec& frame, const ImageSpec& src)
{
    return frame.x == src.x && frame.width == src.width && src.y >= frame.y
           && src.y + src.height <= frame.y + frame.height;
}

/// The frame in the working space: itself, or a converted copy.
bool to_working_space(AlignedFrame& f, const AovSpec& spec, std::string& error)
{
    std::string from, why;
    if (!input_colorspace(from, why, spec, f.frame->spec(), error))
        return false;
    if (!needs_working_conversion(f.frame->spec(), from, f.aovs))
        return true;
    f.converted = std::make_unique<OIIO::ImageBuf>(f.frame->copy(OIIO::TypeDesc::FLOAT));
    if (!into_working_space(*f.converted, f.aovs, from, error))
        return false;
    f.frame = f.converted.get();
    return true;
}

}  // namespace

bool align_neighbours(std::vector<AlignedFrame>& frames, const OIIO::ImageBuf& src,
                      const AovSet& src_aovs, const AovSpec& spec,
                      const std::vector<const OIIO::ImageBuf*>& previous,
                      const std::vector<const OIIO::ImageBuf*>& next,
                      const std::vector<Role>& required, std::string& error)
{
    if (previous.size() > size_t(kMaxNeighbourFrames)
        || next.size() > size_t(kMaxNeighbourFrames)) {
        error = OIIO::Strutil::fmt::format(
            "cross-frame takes at most {} frames on each side ({} and {} given)",
            kMaxNeighbourFrames, previous.size(), next.size());
        return false;
    }
    for (const std::vector<const OIIO::ImageBuf*>* side : { &previous, &next })
        for (const OIIO::ImageBuf* f : *side)
            if (!f) {
                error = "cross-frame: a neighbouring frame is null";
                return false;
            }
    FrameMotion own;
    if (!read_motion(own, src, src_aovs, error)) {
        error = "cross-frame: " + error;
        return false;
    }
    std::vector<Role> roles = required;
    roles.push_back(Role::Motion);
    for (bool backwards : { true, false }) {
        const std::vector<const OIIO::ImageBuf*>& side = backwards ? previous : next;
        std::vector<FrameMotion> motions(side.size());  // of the frames between
        std::vector<const FrameMotion*> steps { &own };
        for (size_t k = 0; k < side.size(); ++k) {
            AlignedFrame f;
            f.offset = backwards ? -int(k + 1) : int(k + 1);
            f.frame = side[k];
            f.name =
                f.frame->name().empty() ? std::string("in memory") : std::string(f.frame->name());
            const ImageSpec& fs = f.frame->spec();
            const ImageSpec& ss = src.spec();
            if (!holds_rows_of(fs, ss)) {
                error = f.error(OIIO::Strutil::fmt::format(
                    "its data window {}x{}+{}+{} does not hold this frame's {}x{}+{}+{}", fs.width,
                    fs.height, fs.x, fs.y, ss.width, ss.height, ss.x, ss.y));
                return false;
            }
            if (!resolve_aovs(f.aovs, spec, fs, error) || !f.aovs.require(roles, fs, error)
                || !to_working_space(f, spec, error)) {
                error = f.error(error);
                return false;
            }
            f.alignment =
                align_frames(steps, backwards, ss.x - fs.x, ss.y - fs.y, fs.width, fs.height);
            if (k + 1 < side.size()) {  // its motion leads to the next one out
                if (!read_motion(motions[k], *f.frame, f.aovs, error)) {
                    error = f.error(error);
                    return false;
                }
                steps.push_back(&motions[k]);
            }
            frames.push_back(std::move(f));
        }
    }
    return true;
}

}  // namespace mcdn
