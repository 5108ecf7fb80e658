#include "core/motion.h"

#include <cmath>

namespace mcdn {

bool read_motion(FrameMotion& motion, const OIIO::ImageBuf& frame, const AovSet& aovs,
                 std::string& error)
{
    if (!aovs.has(Role::Motion)) {
        error = "no motion vectors (role motion: Blender's Vector pass, or "
                "--aov motion=X,Y,Z,W)";
        return false;
    }
    const std::vector<int>& c = aovs.channels(Role::Motion);
    // Blender's convention (the header): towards the previous frame (X, -Y), towards the
    // next (-Z, W), in rows that go down.
    motion.to_previous[0] = read_plane(frame, c[0]);
    motion.to_previous[1] = read_plane(frame, c[1]);
    motion.to_next[0] = read_plane(frame, c[2]);
    motion.to_next[1] = read_plane(frame, c[3]);
    for (Plane* p : { &motion.to_previous[0], &motion.to_previous[1], &motion.to_next[0],
                      &motion.to_next[1] })
        for (float& v : p->px)
            v = std::isfinite(v) ? v : 0.0f;  // no motion known: the pixel stays
    for (float& v : motion.to_previous[1].px)
        v = -v;
    for (float& v : motion.to_next[0].px)
        v = -v;
    return true;
}

double FrameAlignment::inside_fraction() const
{
    size_t inside = 0;
    for (int64_t s : source)
        inside += s >= 0;
    return source.empty() ? 0.0 : double(inside) / double(source.size());
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

}  // namespace mcdn
