// Error metrics against a reference (definitions in metrics.h).
//
// Every metric is first a per-pixel map (mean over the chosen channels, in double); the
// image value is the mean of that map, optionally trimmed. Rows are summed in order, so
// the result does not depend on the thread count.
#include "mcdn/metrics.h"

#include <algorithm>
#include <cmath>
#include <numeric>

#include <OpenImageIO/imagebufalgo.h>
#include <OpenImageIO/parallel.h>
#include <OpenImageIO/strutil.h>

#include "mcdn/threads.h"

namespace mcdn {

using OIIO::ImageSpec;
using OIIO::TypeDesc;
using OIIO::Strutil::fmt::format;

namespace {

// One channel of a buffer over `roi`, as a dense float plane.
std::vector<float> plane(const ImageBuf& buf, const ROI& roi, int channel)
{
    std::vector<float> values(size_t(roi.width()) * roi.height());
    ROI one = roi;
    one.chbegin = channel;
    one.chend = channel + 1;
    buf.get_pixels(one, TypeDesc::FLOAT, values.data());
    return values;
}

struct Planes {
    int width = 0, height = 0;
    std::vector<std::vector<float>> image, reference;  // one plane per chosen channel
};

// Checks sizes and channels, and pulls the chosen channels out as planes.
bool gather(Planes& planes, const ImageBuf& image, const ImageBuf& reference,
            const MetricsOptions& options, ROI roi, std::string& error)
{
    const ImageSpec &is = image.spec(), &rs = reference.spec();
    if (is.width != rs.width || is.height != rs.height) {
        error = format("metrics: image is {}x{} but the reference is {}x{}", is.width, is.height,
                       rs.width, rs.height);
        return false;
    }
    if (options.image_channels.size() != options.reference_channels.size()
        || options.image_channels.empty()) {
        error = "metrics: image and reference channel lists differ in length";
        return false;
    }
    if (!roi.defined())
        roi = image.roi();
    roi = OIIO::roi_intersection(roi, image.roi());
    if (roi.npixels() == 0) {
        error = "metrics: empty region";
        return false;
    }
    // The reference may have a different data-window origin: compare pixel for pixel.
    ROI ref_roi = roi;
    ref_roi.xbegin += rs.x - is.x;
    ref_roi.xend += rs.x - is.x;
    ref_roi.ybegin += rs.y - is.y;
    ref_roi.yend += rs.y - is.y;
    planes.width = roi.width();
    planes.height = roi.height();
    for (size_t i = 0; i < options.image_channels.size(); ++i) {
        int ic = options.image_channels[i], rc = options.reference_channels[i];
        if (ic < 0 || ic >= is.nchannels || rc < 0 || rc >= rs.nchannels) {
            error = format("metrics: channel {} (image) or {} (reference) does not exist", ic, rc);
            return false;
        }
        planes.image.push_back(plane(image, roi, ic));
        planes.reference.push_back(plane(reference, ref_roi, rc));
        for (const auto* p : { &planes.image.back(), &planes.reference.back() }) {
            auto bad =
                std::find_if(p->begin(), p->end(), [](float v) { return !std::isfinite(v); });
            if (bad != p->end()) {
                size_t k = size_t(bad - p->begin());
                const ImageSpec& s = p == &planes.image.back() ? is : rs;
                int c = p == &planes.image.back() ? ic : rc;
                error =
                    format("metrics: {} channel '{}' is not finite at pixel ({}, {})",
                           p == &planes.image.back() ? "image" : "reference", s.channel_name(c),
                           roi.xbegin + int(k % roi.width()), roi.ybegin + int(k / roi.width()));
                return false;
            }
        }
    }
    return true;
}

// Per-pixel error of one kind, mean over channels.
std::vector<double> per_pixel(const Planes& planes, ErrorKind kind, const MetricsOptions& o)
{
    size_t n = size_t(planes.width) * planes.height;
    size_t nc = planes.image.size();
    std::vector<double> map(n, 0.0);
    for (size_t c = 0; c < nc; ++c) {
        const auto &x = planes.image[c], &r = planes.reference[c];
        for (size_t p = 0; p < n; ++p) {
            double d = double(x[p]) - double(r[p]);
            double e = 0;
            switch (kind) {
            case ErrorKind::SquaredError: e = d * d; break;
            case ErrorKind::AbsoluteError: e = std::fabs(d); break;
            case ErrorKind::RelMSE: e = d * d / (double(r[p]) * r[p] + o.relmse_epsilon); break;
            case ErrorKind::SMAPE:
                e = std::fabs(d)
                    / (std::fabs(double(x[p])) + std::fabs(double(r[p])) + o.smape_epsilon);
                break;
            }
            map[p] += e / double(nc);
        }
    }
    return map;
}

// Separable Gaussian blur (sigma 1.5, 11 taps) with clamp-to-edge borders.
std::vector<double> gaussian_blur(const std::vector<double>& in, int w, int h)
{
    constexpr int radius = 5;
    double taps[2 * radius + 1], total = 0;
    for (int i = -radius; i <= radius; ++i)
        total += taps[i + radius] = std::exp(-0.5 * i * i / (1.5 * 1.5));
    for (double& t : taps)
        t /= total;
    std::vector<double> tmp(in.size()), out(in.size());
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double s = 0;
            for (int i = -radius; i <= radius; ++i)
                s += taps[i + radius] * in[size_t(y) * w + std::clamp(x + i, 0, w - 1)];
            tmp[size_t(y) * w + x] = s;
        }
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double s = 0;
            for (int i = -radius; i <= radius; ++i)
                s += taps[i + radius] * tmp[size_t(std::clamp(y + i, 0, h - 1)) * w + x];
            out[size_t(y) * w + x] = s;
        }
    return out;
}

// Per-pixel SSIM (Wang et al. 2004), mean over channels, on values clamped to [0, 1].
std::vector<double> ssim_map(const Planes& planes)
{
    const int w = planes.width, h = planes.height;
    const size_t n = size_t(w) * h, nc = planes.image.size();
    constexpr double C1 = 0.01 * 0.01, C2 = 0.03 * 0.03;
    std::vector<double> map(n, 0.0);
    for (size_t c = 0; c < nc; ++c) {
        std::vector<double> x(n), y(n), xx(n), yy(n), xy(n);
        for (size_t p = 0; p < n; ++p) {
            x[p] = std::clamp(double(planes.image[c][p]), 0.0, 1.0);
            y[p] = std::clamp(double(planes.reference[c][p]), 0.0, 1.0);
            xx[p] = x[p] * x[p];
            yy[p] = y[p] * y[p];
            xy[p] = x[p] * y[p];
        }
        auto mx = gaussian_blur(x, w, h), my = gaussian_blur(y, w, h);
        auto sxx = gaussian_blur(xx, w, h), syy = gaussian_blur(yy, w, h),
             sxy = gaussian_blur(xy, w, h);
        for (size_t p = 0; p < n; ++p) {
            double vx = sxx[p] - mx[p] * mx[p], vy = syy[p] - my[p] * my[p];
            double cov = sxy[p] - mx[p] * my[p];
            double s = ((2 * mx[p] * my[p] + C1) * (2 * cov + C2))
                       / ((mx[p] * mx[p] + my[p] * my[p] + C1) * (vx + vy + C2));
            map[p] += s / double(nc);
        }
    }
    return map;
}

// Mean of a per-pixel map; with trimming, the best and worst `fraction` are dropped.
double mean(std::vector<double> map, bool trim, double fraction, long long* count)
{
    size_t drop = trim ? size_t(std::floor(double(map.size()) * fraction)) : 0;
    if (drop > 0) {
        std::sort(map.begin(), map.end());
        map = std::vector<double>(map.begin() + drop, map.end() - drop);
    }
    if (count)
        *count = (long long)map.size();
    // Pairwise-free but ordered: std::accumulate in index order is deterministic.
    return map.empty() ? 0.0 : std::accumulate(map.begin(), map.end(), 0.0) / double(map.size());
}

}  // namespace

bool compute_metrics(Metrics& m, const ImageBuf& image, const ImageBuf& reference,
                     const MetricsOptions& o, std::string& error, ROI roi, int nthreads)
{
    Planes planes;
    if (!check_threads(nthreads, error) || !gather(planes, image, reference, o, roi, error))
        return false;
    m = Metrics();
    m.mse = mean(per_pixel(planes, ErrorKind::SquaredError, o), o.trim, o.trim_fraction, &m.pixels);
    m.rmse = std::sqrt(m.mse);
    m.relmse = mean(per_pixel(planes, ErrorKind::RelMSE, o), o.trim, o.trim_fraction, nullptr);
    m.smape = mean(per_pixel(planes, ErrorKind::SMAPE, o), o.trim, o.trim_fraction, nullptr);
    m.psnr = m.mse > 0 ? std::min(999.0, 10.0 * std::log10(1.0 / m.mse)) : 999.0;
    m.ssim = mean(ssim_map(planes), o.trim, o.trim_fraction, nullptr);
    return true;
}

namespace {

// The four pixels around (x, y) in pixel-centre coordinates and the fractions between them;
// false outside the plane. The last row and column interpolate towards themselves (fx or fy
// is then 1 or 0).
bool bilinear(int w, int h, double x, double y, size_t at[4], double& fx, double& fy)
{
    if (!(x >= 0 && y >= 0 && x <= w - 1 && y <= h - 1))
        return false;
    const int x0 = std::min(int(x), std::max(0, w - 2)), y0 = std::min(int(y), std::max(0, h - 2));
    const int x1 = std::min(x0 + 1, w - 1), y1 = std::min(y0 + 1, h - 1);
    fx = x - x0;
    fy = y - y0;
    at[0] = size_t(y0) * w + x0;
    at[1] = size_t(y0) * w + x1;
    at[2] = size_t(y1) * w + x0;
    at[3] = size_t(y1) * w + x1;
    return true;
}

// Bilinear sample of a plane at (x, y); false outside.
bool sample(const std::vector<float>& plane, int w, int h, double x, double y, double& value)
{
    size_t at[4];
    double fx, fy;
    if (!bilinear(w, h, x, y, at, fx, fy))
        return false;
    auto v = [&](int i) { return double(plane[at[i]]); };
    value = (1 - fy) * ((1 - fx) * v(0) + fx * v(1)) + fy * ((1 - fx) * v(2) + fx * v(3));
    return true;
}

// The variance of that sample for a plane of independent values of variance `var`: the
// squared weights times the variances.
bool sample_variance(const std::vector<float>& var, int w, int h, double x, double y, double& value)
{
    size_t at[4];
    double fx, fy;
    if (!bilinear(w, h, x, y, at, fx, fy))
        return false;
    auto v = [&](int i) { return std::max(0.0, double(var[at[i]])); };
    const double gx = 1 - fx, gy = 1 - fy;
    value =
        gy * gy * (gx * gx * v(0) + fx * fx * v(1)) + fy * fy * (gx * gx * v(2) + fx * fx * v(3));
    return true;
}

// The motion planes (m_x, m_y) in pixels, zero without a motion buffer.
bool motion_planes(std::vector<float>& mx, std::vector<float>& my, const ImageBuf* motion, int w,
                   int h, const TemporalOptions& o, std::string& error)
{
    mx.assign(size_t(w) * h, 0.0f);
    my.assign(mx.size(), 0.0f);
    if (!motion)
        return true;
    const ImageSpec& ms = motion->spec();
    if (ms.width != w || ms.height != h || o.motion_x < 0 || o.motion_y < 0
        || std::max(o.motion_x, o.motion_y) >= ms.nchannels) {
        error = format("metrics: the motion vectors ({}x{}, {} channels) do not match the "
                       "{}x{} frame or channels {}, {}",
                       ms.width, ms.height, ms.nchannels, w, h, o.motion_x, o.motion_y);
        return false;
    }
    mx = plane(*motion, motion->roi(), o.motion_x);
    my = plane(*motion, motion->roi(), o.motion_y);
    for (const auto* v : { &mx, &my })
        if (std::any_of(v->begin(), v->end(), [](float f) { return !std::isfinite(f); })) {
            error = format("metrics: motion channel '{}' is not finite",
                           ms.channel_name(v == &mx ? o.motion_x : o.motion_y));
            return false;
        }
    return true;
}

// Frame t's and frame t-1's planes (gather's pairs: image and reference each) and the motion
// between them, checked.
bool gather_frames(Planes& now, Planes& before, std::vector<float>& mx, std::vector<float>& my,
                   const ImageBuf& image, const ImageBuf& reference, const ImageBuf& previous,
                   const ImageBuf& previous_reference, const ImageBuf* motion,
                   const MetricsOptions& channels, const TemporalOptions& o, std::string& error)
{
    if (!gather(now, image, reference, channels, {}, error))
        return false;
    if (!gather(before, previous, previous_reference, channels, {}, error)) {
        error = "previous frame: " + error;
        return false;
    }
    if (before.width != now.width || before.height != now.height) {
        error = format("metrics: the previous frame is {}x{} but this one is {}x{}", before.width,
                       before.height, now.width, now.height);
        return false;
    }
    return motion_planes(mx, my, motion, now.width, now.height, o, error);
}

// Per pixel p of frame t whose position in frame t-1 (p + m(p)) lies inside it, in pixel
// order: the mean over channels of a squared term, plain into `squared` and over
// r_t(p)^2 + epsilon into `relative`. term(c, p, px, py, value) sets channel c's term; false
// outside frame t-1.
template <class Term>
void warped_means(int w, int h, const std::vector<std::vector<float>>& r,
                  const std::vector<float>& mx, const std::vector<float>& my,
                  const TemporalOptions& o, std::vector<double>& squared,
                  std::vector<double>& relative, Term term)
{
    const size_t nc = r.size();
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            const size_t p = size_t(y) * w + x;
            const double px = x + o.motion_scale_x * mx[p];
            const double py = double(y) + o.motion_scale_y * my[p];
            double sq = 0, rel = 0;
            bool ok = true;
            for (size_t c = 0; c < nc && ok; ++c) {
                double v = 0;
                ok = term(c, p, px, py, v);
                const double rc = r[c][p];
                sq += v / double(nc);
                rel += v / (rc * rc + o.metrics.relmse_epsilon) / double(nc);
            }
            if (ok) {
                squared.push_back(sq);
                relative.push_back(rel);
            }
        }
}

}  // namespace

bool compute_temporal_metrics(TemporalMetrics& m, const ImageBuf& image, const ImageBuf& previous,
                              const ImageBuf& reference, const ImageBuf& previous_reference,
                              const ImageBuf* motion, const TemporalOptions& o, std::string& error,
                              int nthreads)
{
    Planes now, before;
    std::vector<float> mx, my;
    if (!check_threads(nthreads, error)
        || !gather_frames(now, before, mx, my, image, reference, previous, previous_reference,
                          motion, o.metrics, o, error))
        return false;
    const int w = now.width, h = now.height;
    // Per pixel inside frame t-1: (e_t - W e_{t-1})^2, mean over channels, and its relative
    // form (one pass, cheap beside reading the frames).
    std::vector<double> squared, relative;
    warped_means(w, h, now.reference, mx, my, o, squared, relative,
                 [&](size_t c, size_t p, double px, double py, double& value) {
                     double x_before = 0, r_before = 0;
                     if (!sample(before.image[c], w, h, px, py, x_before)
                         || !sample(before.reference[c], w, h, px, py, r_before))
                         return false;
                     const double r = now.reference[c][p];
                     const double d = (double(now.image[c][p]) - r) - (x_before - r_before);
                     value = d * d;
                     return true;
                 });
    m = TemporalMetrics();
    m.mse = mean(squared, o.metrics.trim, o.metrics.trim_fraction, &m.pixels);
    m.relmse = mean(relative, o.metrics.trim, o.metrics.trim_fraction, nullptr);
    if (m.pixels == 0) {
        error = "metrics: no pixel of this frame was inside the previous one";
        return false;
    }
    return true;
}

bool compute_reference_noise(ReferenceNoise& result, const ImageBuf& reference,
                             const ImageBuf& variance, const MetricsOptions& o, std::string& error,
                             ROI roi, int nthreads)
{
    MetricsOptions both = o;
    both.image_channels = o.reference_channels;
    Planes planes;  // image: the reference, reference: its variance
    if (!check_threads(nthreads, error) || !gather(planes, reference, variance, both, roi, error))
        return false;
    const size_t n = size_t(planes.width) * planes.height, nc = planes.image.size();
    std::vector<double> squared(n, 0.0), relative(n, 0.0);
    for (size_t c = 0; c < nc; ++c)
        for (size_t p = 0; p < n; ++p) {
            const double r = planes.image[c][p], v = std::max(0.0, double(planes.reference[c][p]));
            squared[p] += v / double(nc);
            relative[p] += v / (r * r + o.relmse_epsilon) / double(nc);
        }
    result.mse = mean(squared, false, 0, nullptr);
    result.relmse = mean(relative, false, 0, nullptr);
    return true;
}

bool compute_temporal_reference_noise(ReferenceNoise& result, const ImageBuf& reference,
                                      const ImageBuf& variance, const ImageBuf& previous_variance,
                                      const ImageBuf* motion, const TemporalOptions& o,
                                      std::string& error, int nthreads)
{
    MetricsOptions both = o.metrics;
    both.image_channels = o.metrics.reference_channels;
    Planes now, before;  // image: the reference, reference: the variance
    std::vector<float> mx, my;
    if (!check_threads(nthreads, error)
        || !gather_frames(now, before, mx, my, reference, variance, reference, previous_variance,
                          motion, both, o, error))
        return false;
    const int w = now.width, h = now.height;
    // The pixels compute_temporal_metrics keeps: those inside frame t-1.
    std::vector<double> squared, relative;
    warped_means(w, h, now.image, mx, my, o, squared, relative,
                 [&](size_t c, size_t p, double px, double py, double& value) {
                     double v_before = 0;
                     if (!sample_variance(before.reference[c], w, h, px, py, v_before))
                         return false;
                     value = std::max(0.0, double(now.reference[c][p])) + v_before;
                     return true;
                 });
    if (squared.empty()) {
        error = "metrics: no pixel of this frame was inside the previous one";
        return false;
    }
    result.mse = mean(squared, false, 0, nullptr);
    result.relmse = mean(relative, false, 0, nullptr);
    return true;
}

bool error_map(ImageBuf& dst, const ImageBuf& image, const ImageBuf& reference,
               const MetricsOptions& options, ErrorKind kind, ROI roi, int nthreads)
{
    Planes planes;
    std::string error;
    if (!check_threads(nthreads, error) || !gather(planes, image, reference, options, roi, error)) {
        dst.errorfmt("{}", error);
        return false;
    }
    std::vector<double> map = per_pixel(planes, kind, options);
    ROI where = roi.defined() ? OIIO::roi_intersection(roi, image.roi()) : image.roi();
    ImageSpec spec(where.width(), where.height(), 1, TypeDesc::FLOAT);
    spec.x = where.xbegin;
    spec.y = where.ybegin;
    spec.channelnames = { "error" };
    dst.reset(spec);
    std::vector<float> values(map.begin(), map.end());
    dst.set_pixels(dst.roi(), TypeDesc::FLOAT, values.data());
    return true;
}

bool heatmap(ImageBuf& dst, const ImageBuf& error, double log10_min, double log10_max, ROI roi,
             int nthreads)
{
    if (!(log10_max > log10_min)) {
        dst.errorfmt("heatmap: range [{}, {}] is empty", log10_min, log10_max);
        return false;
    }
    std::string why;
    if (!check_threads(nthreads, why)) {
        dst.errorfmt("heatmap: {}", why);
        return false;
    }
    // Map log10(error) to [0, 1]; color_map does the false colour.
    ImageBuf scaled(error.spec());
    const ROI where = roi.defined() ? roi : error.roi();
    std::vector<float> values(size_t(where.width()) * where.height());
    ROI one = where;
    one.chbegin = 0;
    one.chend = 1;
    error.get_pixels(one, TypeDesc::FLOAT, values.data());
    for (float& v : values) {
        double l = std::log10(std::max(double(v), 1e-30));
        v = float(std::clamp((l - log10_min) / (log10_max - log10_min), 0.0, 1.0));
    }
    scaled.set_pixels(one, TypeDesc::FLOAT, values.data());
    return OIIO::ImageBufAlgo::color_map(dst, scaled, 0, "inferno", where, nthreads);
}

std::string format_metrics(const Metrics& m, bool json)
{
    if (json)
        return format("{{\"mse\": {:.6g}, \"rmse\": {:.6g}, \"relmse\": {:.6g}, "
                      "\"smape\": {:.6g}, \"psnr\": {:.6g}, \"ssim\": {:.6g}, \"pixels\": {}}}",
                      m.mse, m.rmse, m.relmse, m.smape, m.psnr, m.ssim, m.pixels);
    return format("MSE    {:.6g}\nRMSE   {:.6g}\nrelMSE {:.6g}\nSMAPE  {:.6g}\nPSNR   {:.4g} dB\n"
                  "SSIM   {:.6g}\npixels {}\n",
                  m.mse, m.rmse, m.relmse, m.smape, m.psnr, m.ssim, m.pixels);
}

}  // namespace mcdn
