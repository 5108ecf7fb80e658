// What the whole frame decides when a chain runs it in bands of rows (chain/chain_bands.cpp):
// each band's spec carries the frame's statistics, so that every stage run on the band
// computes what it would on the whole frame. Without them (a stage run on a whole frame) the
// stages compute the same numbers from their own input, with the same formulas below.
#pragma once

#include <algorithm>
#include <cfloat>
#include <cstdint>
#include <map>
#include <string>
#include <vector>

#include <OpenImageIO/imagebuf.h>

namespace mcdn {

/// The attribute a band's spec carries them in (removed from every stage's output).
constexpr const char* kFrameFactsAttribute = "mcdn:frame";

/// Sums over the colour's three channels and every pixel: each channel's summed in row
/// order, then the three added (combined()), whatever reads the rows — the whole frame, or
/// a chain's light pass a band at a time — so the doubles are the same.
struct ColorSums {
    double sum_abs = 0;        // |x|
    double sum_sd = 0;         // sqrt of the variance of the mean (sanitized): the probe's scale
    double sum = 0, sum2 = 0;  // x and x² (the t-test's image variance)
    uint64_t n = 0;
};

/// The sums of src's colour channels (and, when given, their variance channels), read a few
/// rows at a time: the same doubles for any band size.
ColorSums color_sums(const OIIO::ImageBuf& src, const int color[3], const int variance[3]);
/// Adds src's rows to each channel's sums (part[c]: colour channel c), for a frame read in
/// bands of rows top to bottom; combined() then gives colour_sums of the whole.
void add_color_sums(ColorSums part[3], const OIIO::ImageBuf& src, const int color[3],
                    const int variance[3]);
ColorSums combined(const ColorSums part[3]);

/// eps such that eps * mean(sqrt(Var)) = relative * mean|x| (b = sqrt(Var) n): SURE's probe
/// step (PD §3.2) and one-buffer NFOR's; 0 when there is nothing to probe. The mean of the
/// standard deviations, not their RMS: on a heavy-tailed render (a caustic through glass)
/// a few pixels' variance is a million times the others', the RMS is theirs, and a step
/// scaled by it moves the typical pixel by less than the denoiser's float rounding, so that
/// the finite difference of eq. 2 measures the rounding (|f'| in the hundreds).
double relative_probe_step(const ColorSums& sums, double relative);
/// The t-test's sigma_s (PD §4.3): min(sqrt(Var[x]), 1) * scale, Var[x] over the frame.
float t_test_sigma(const ColorSums& sums, float scale);

/// Running sums of the autoexposure (Open Image Denoise's, which its networks were trained
/// with): the frame cut into a grid of about 16×16
/// pixel bins (ceil(H / 16) × ceil(W / 16), bin i of n covering [i·H/n, (i+1)·H/n)), each
/// bin's mean luminance (Rec. 709 weights, NaN as 0, negatives clamped to 0); the scale is
/// 0.18 over the geometric mean of the bins' means above 1e-8 (1 when none is). Rows come
/// top to bottom, a band at a time or the whole frame: the same scale.
class Autoexposure {
public:
    Autoexposure(int width, int height);
    /// Adds rows [y0, y1) of the frame (frame coordinates 0..height), `rgb(x, y, c)` their
    /// colour.
    template <class Rgb> void add_rows(int y0, int y1, Rgb rgb);
    /// The same for all rows of `rows` (the frame's rows from `first_row` on), its colour
    /// channels `colour`.
    void add_rows(const OIIO::ImageBuf& rows, const int color[3], int first_row);
    /// The exposure scale of the frame once every row is added.
    float scale() const;

private:
    static float clamped(float v) { return v > 0 ? std::min(v, FLT_MAX) : 0.0f; }  // NaN: 0
    void end_row(int y);
    int m_width, m_height, m_bins_x, m_bins_y, m_bin_row = 0;
    std::vector<int> m_bin_of_x;
    std::vector<double> m_sums;  // the current row of bins
    double m_log_sum = 0;
    long m_count = 0;
};

template <class Rgb> void Autoexposure::add_rows(int y0, int y1, Rgb rgb)
{
    for (int y = y0; y < y1; ++y) {
        for (int x = 0; x < m_width; ++x)
            m_sums[size_t(m_bin_of_x[size_t(x)])] += 0.212671f * clamped(rgb(x, y, 0))
                                                     + 0.715160f * clamped(rgb(x, y, 1))
                                                     + 0.072169f * clamped(rgb(x, y, 2));
        end_row(y);
    }
}

/// The autoexposure scale of src's colour channels `colour` (whole frame).
float autoexposure(const OIIO::ImageBuf& src, const int color[3]);

struct FrameFacts {
    int ybegin = 0, yend = 0;  // the frame's rows (a band's own are its spec's)
    ColorSums color;
    /// The CNN's depth range (0, 0: no depth), when known.
    bool has_depth = false;
    float depth_lo = 0, depth_span = 0;
    /// The autoexposure scale of the colour (Autoexposure below: OIDN's networks), when known.
    bool has_exposure = false;
    float exposure = 1;
    /// Channels holding one value over the frame (after sanitizing), with that value: the
    /// constant features nfor and prefilter leave out (skip/constant_features.h), when known.
    bool has_constant = false;
    std::map<std::string, float> constant;
};

/// The facts a spec carries; false when it has none. A chain's bands carry all of them;
/// the inputs sure hands its denoiser carry at least the unprobed frame's colour sums, so
/// that the denoiser is the same function of its input for every probe (one-buffer NFOR's
/// probe step).
bool frame_facts(FrameFacts& facts, const OIIO::ImageSpec& spec);
void set_frame_facts(OIIO::ImageSpec& spec, const FrameFacts& facts);

/// A band of a larger frame (its facts' rows are not its own), which a chain or sure cut
/// already: the ops' own bands would only add halos (each runs it whole).
bool is_frame_band(const OIIO::ImageSpec& spec);

}  // namespace mcdn
