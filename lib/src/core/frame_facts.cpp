#include "core/frame_facts.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>

#include <OpenImageIO/strutil.h>

#include "core/planar.h"

namespace mcdn {

namespace Strutil = OIIO::Strutil;

void add_color_sums(ColorSums part[3], const OIIO::ImageBuf& src, const int color[3],
                    const int variance[3])
{
    const OIIO::ROI whole = src.roi();
    const int rows_per_read = std::max(1, int((int64_t(1) << 20) / std::max(1, whole.width())));
    for (int c = 0; c < 3; ++c)
        for (int y = whole.ybegin; y < whole.yend; y += rows_per_read) {
            OIIO::ROI rows = whole;
            rows.ybegin = y;
            rows.yend = std::min(y + rows_per_read, whole.yend);
            ColorSums& s = part[c];
            const Plane x = read_rows(src, color[c], rows);
            for (float v : x.px) {
                s.sum_abs += std::fabs(v);
                s.sum += v;
                s.sum2 += double(v) * v;
            }
            if (variance)
                for (float v : read_rows(src, variance[c], rows, true).px)
                    s.sum_sd += std::sqrt(v);
            s.n += x.size();
        }
}

ColorSums combined(const ColorSums part[3])
{
    ColorSums s;
    for (int c = 0; c < 3; ++c) {
        s.sum_abs += part[c].sum_abs;
        s.sum_sd += part[c].sum_sd;
        s.sum += part[c].sum;
        s.sum2 += part[c].sum2;
        s.n += part[c].n;
    }
    return s;
}

ColorSums color_sums(const OIIO::ImageBuf& src, const int color[3], const int variance[3])
{
    ColorSums part[3];
    add_color_sums(part, src, color, variance);
    return combined(part);
}

double relative_probe_step(const ColorSums& s, double relative)
{
    if (s.n == 0 || s.sum_sd <= 0 || s.sum_abs <= 0)
        return 0;  // no noise, or a black image: nothing to probe
    return relative * s.sum_abs / s.sum_sd;
}

float t_test_sigma(const ColorSums& s, float scale)
{
    // "Var[x-bar], x-bar the image mean": the spatial variance of the render's values over
    // all pixels and channels (capped at 1 before the square root, as in the paper).
    const double mean = s.n ? s.sum / s.n : 0;
    const double variance = s.n ? std::max(0.0, s.sum2 / s.n - mean * mean) : 0;
    return float(std::min(std::sqrt(variance), 1.0) * scale);
}

namespace {

// Doubles and floats as C99 hex floats: read back bit for bit.
std::string hex(double v)
{
    char text[64];
    std::snprintf(text, sizeof text, "%a", v);
    return text;
}

}  // namespace

Autoexposure::Autoexposure(int width, int height)
    : m_width(width), m_height(height), m_bins_x((width + 15) / 16), m_bins_y((height + 15) / 16)
{
    m_bin_of_x.resize(size_t(std::max(width, 0)));
    for (int b = 0; b < m_bins_x; ++b)
        for (int x = int(int64_t(b) * width / m_bins_x); x < int(int64_t(b + 1) * width / m_bins_x);
             ++x)
            m_bin_of_x[size_t(x)] = b;
    m_sums.assign(size_t(m_bins_x), 0.0);
}

void Autoexposure::end_row(int y)
{
    const int end = int(int64_t(m_bin_row + 1) * m_height / m_bins_y);
    if (y + 1 < end)
        return;
    const int rows = end - int(int64_t(m_bin_row) * m_height / m_bins_y);
    for (int b = 0; b < m_bins_x; ++b) {
        const int columns =
            int(int64_t(b + 1) * m_width / m_bins_x) - int(int64_t(b) * m_width / m_bins_x);
        const double mean = m_sums[size_t(b)] / (double(rows) * columns);
        if (mean > 1e-8) {
            m_log_sum += std::log2(mean);
            ++m_count;
        }
        m_sums[size_t(b)] = 0.0;
    }
    ++m_bin_row;
}

float Autoexposure::scale() const
{
    return m_count > 0 ? float(0.18 / std::exp2(m_log_sum / double(m_count))) : 1.0f;
}

void Autoexposure::add_rows(const OIIO::ImageBuf& rows, const int color[3], int first_row)
{
    const OIIO::ImageSpec& spec = rows.spec();
    std::vector<float> row(size_t(spec.width) * 3);
    for (int y = 0; y < spec.height; ++y) {
        for (int c = 0; c < 3; ++c)
            rows.get_pixels(OIIO::ROI(spec.x, spec.x + spec.width, spec.y + y, spec.y + y + 1, 0, 1,
                                      color[c], color[c] + 1),
                            OIIO::TypeDesc::FLOAT, row.data() + c, 3 * sizeof(float));
        add_rows(first_row + y, first_row + y + 1,
                 [&](int x, int, int c) { return row[size_t(x) * 3 + size_t(c)]; });
    }
}

float autoexposure(const OIIO::ImageBuf& src, const int color[3])
{
    Autoexposure exposure(src.spec().width, src.spec().height);
    exposure.add_rows(src, color, 0);
    return exposure.scale();
}

void set_frame_facts(OIIO::ImageSpec& spec, const FrameFacts& f)
{
    // One line per value; channel names (which may hold spaces) last on their line.
    std::string text = Strutil::fmt::format("rows {} {}\ncolour {} {} {} {} {}\n", f.ybegin, f.yend,
                                            hex(f.color.sum_abs), hex(f.color.sum_sd),
                                            hex(f.color.sum), hex(f.color.sum2), f.color.n);
    if (f.has_depth)
        text += Strutil::fmt::format("depth {} {}\n", hex(f.depth_lo), hex(f.depth_span));
    if (f.has_exposure)
        text += Strutil::fmt::format("exposure {}\n", hex(f.exposure));
    if (f.has_constant) {
        text += "constants known\n";
        for (const auto& [name, value] : f.constant)
            text += "constant " + hex(value) + " " + name + "\n";
    }
    spec.attribute(kFrameFactsAttribute, text);
}

bool frame_facts(FrameFacts& f, const OIIO::ImageSpec& spec)
{
    const std::string text = spec.get_string_attribute(kFrameFactsAttribute);
    if (text.empty())
        return false;
    f = FrameFacts();
    for (const std::string& line : Strutil::splits(text, "\n")) {
        const std::vector<std::string> w = Strutil::splits(line, " ");
        if (w.empty())
            continue;
        auto number = [&](size_t i) {
            return i < w.size() ? std::strtod(w[i].c_str(), nullptr) : 0.0;
        };
        if (w[0] == "rows") {
            f.ybegin = int(number(1));
            f.yend = int(number(2));
        } else if (w[0] == "colour") {
            f.color = { number(1), number(2), number(3), number(4),
                        w.size() > 5 ? std::strtoull(w[5].c_str(), nullptr, 10) : 0 };
        } else if (w[0] == "depth") {
            f.has_depth = true;
            f.depth_lo = float(number(1));
            f.depth_span = float(number(2));
        } else if (w[0] == "exposure") {
            f.has_exposure = true;
            f.exposure = float(number(1));
        } else if (w[0] == "constants") {
            f.has_constant = true;
        } else if (w[0] == "constant" && w.size() > 2) {
            const size_t at = line.find(' ', line.find(' ') + 1) + 1;
            f.constant[line.substr(at)] = float(number(1));
        }
    }
    return true;
}

bool is_frame_band(const OIIO::ImageSpec& spec)
{
    FrameFacts f;
    return frame_facts(f, spec) && (f.ybegin != spec.y || f.yend != spec.y + spec.height);
}

}  // namespace mcdn
