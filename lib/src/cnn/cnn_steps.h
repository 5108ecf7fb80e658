// The steps of the KPCN op (lib/src/cnn/cnn.cpp), exposed for the tests: the raw planes of
// the render (the diffuse/specular split, KPCN §4.3), the network inputs of a branch (§5.1),
// and the two branch networks (§4.2). training/cnn/{data,model}.py compute the same.
#pragma once

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include "core/planar.h"
#include "mcdn/aov.h"
#include "nn/nn.h"

namespace mcdn {
struct ExtraPlanes;  // core/extra_aovs.h

namespace kpcn {

constexpr const char* kInputLayout = "kpcn-cpu-1";  // model.py INPUT_LAYOUT
constexpr int kInputChannels = 34;
constexpr float kAlbedoEpsilon = 0.00316f;  // §4.3
constexpr float kInputLimit = 1e3f;         // network inputs clamped to +-this
constexpr int kKernel = 5;                  // each reconstruction step is 5×5

/// What the op reads, one plane per channel, sanitized (finite), on a rectangle of the frame
/// (a network tile's window, or the whole frame). Depth is unscaled until scale_depth().
/// Without a split, diffuse is zero and specular is the colour.
struct RawPlanes {
    bool split = false;
    Rect rect;  // where the planes lie in the frame
    int frame_width = 0, frame_height = 0;
    Plane color[3], color_var[3];
    Plane diffuse[3], diffuse_var[3];
    Plane specular[3], specular_var[3];
    Plane demod[3];  // the albedo divided out of the diffuse part (DiffCol)
    Plane albedo[3], albedo_var[3], normal[3], normal_var[3], depth, depth_var;
    int width() const { return color[0].width; }
    int height() const { return color[0].height; }
};

/// Reads the raw planes (training/cnn/data.py load_render) of `rect` (empty: the whole
/// frame). Component variances: the delta method over the passes, Var[C (D + I)] ~ C² (Var D
/// + Var I) + (D + I)² Var C, passes taken as independent; where a pass has no variance
/// channel, the colour's variance.
bool read_raw_planes(RawPlanes& raw, const ImageBuf& src, const AovSet& aovs, std::string& error,
                     Rect rect = {});
/// Whether the render has the diffuse/specular split of §4.3 (Blender's diffuse passes, or
/// the generic preset's diffuse role): then eq. 4 adds two branches, else the specular
/// branch denoises the colour alone.
bool has_split(const AovSet& aovs);
/// Eq. 4's factor on `rect` of the frame: the albedo divided out of the diffuse (sanitized).
void read_demod(Plane demod[3], const ImageBuf& src, const AovSet& aovs, Rect rect);

/// §5.1 scales depth linearly to [0, 1] over the frame: the one input statistic of the
/// whole frame, so it is taken before the tiles. span <= 0: constant depth (scaled to 0).
struct DepthRange {
    float lo = 0, span = 0;
    float hi = 0;  // the largest depth (lo + span may round off it): for merging ranges
};
/// The range of the (sanitized) depth feature of src; read in bands, no whole-frame plane.
DepthRange depth_range(const ImageBuf& src, const AovSet& aovs);
DepthRange depth_range(const Plane& depth);
/// Depth to [0, 1] by the frame's range (its variance by the same factor²).
void scale_depth(RawPlanes& raw, const DepthRange& range);
inline void scale_depth(RawPlanes& raw)
{
    scale_depth(raw, depth_range(raw.depth));
}

enum class Branch { diffuse, specular };

/// The op's output frame, a float copy of the render in memory (prepare_op): each tile
/// writes its own pixels straight into it, from any worker.
class OutputFrame {
public:
    explicit OutputFrame(ImageBuf& dst)
        : base_(static_cast<char*>(dst.localpixels())), pixel_bytes_(size_t(dst.pixel_stride())),
          row_bytes_(size_t(dst.scanline_stride()))
    { }
    bool valid() const { return base_ != nullptr; }
    /// The channels of pixel (x, y), counted from the data window's corner.
    float* pixel(int x, int y)
    {
        return reinterpret_cast<float*>(base_ + size_t(y) * row_bytes_ + size_t(x) * pixel_bytes_);
    }

private:
    char* base_;
    size_t pixel_bytes_, row_bytes_;
};

/// Heavy-tailed pixels taken out of the network's input (CnnOptions::outliers): the colour's
/// mean and variance each gets (its neighbourhood's medians) and the factor its diffuse and
/// specular parts are scaled by (that mean over the render's, per channel, in [0, 1]).
struct DroppedOutliers {
    std::vector<uint32_t> pixels;  // y * width + x in the frame, ascending
    std::vector<std::array<float, 3>> mean, variance, scale;
    bool empty() const { return pixels.empty(); }
};
/// Puts the outliers that lie in raw.rect into planes read by read_raw_planes.
void drop_outliers(RawPlanes& raw, const DroppedOutliers& outliers);

/// The frame pixels a network tile's inputs are computed from: the window clipped to the
/// frame (past it, the last row and column stand for the rest), and one more column and row
/// (the forward differences of its last ones).
Rect inputs_rect(const Rect& window, int frame_width, int frame_height);

/// The 34 network input channels of a branch (layout in training/cnn/model.py) and the image
/// its kernels filter: irradiance = diffuse / (demod + eps), or log(1 + specular); on the
/// `window` of the frame extended as nn::run_tiled extends it (rows and columns past the
/// frame repeat its last), from raw planes covering inputs_rect(window). The tensors' storage
/// is reused.
void branch_inputs(const RawPlanes& raw, Branch branch, const Rect& window, nn::Tensor& features,
                   nn::Tensor& image);
/// The same on the whole frame of `raw` (the bench's and the tests' whole-frame inputs).
void branch_inputs(const RawPlanes& raw, Branch branch, nn::Tensor& features, nn::Tensor& image);

/// A branch network's two inputs for one tile: the 34 feature channels and the image its
/// kernels filter (with extras, their parts after the colour's: extras_kernels.h).
struct BranchInputs {
    std::vector<nn::Tensor> tensors = std::vector<nn::Tensor>(2);  // as Net::run takes them
    nn::Tensor& features() { return tensors[0]; }
    nn::Tensor& image() { return tensors[1]; }
};

/// The inputs of both branches on a tile's window (diffuse null: the specular branch alone,
/// as without a split): read_raw_planes, drop_outliers (when given), scale_depth and
/// branch_inputs in strips of rows,
/// each strip read once for both and computed in cache, threaded; the extras' parts
/// appended to the images (extras_kernels.h). The tensors' storage is reused.
bool tile_inputs(const ImageBuf& src, const AovSet& aovs, const DepthRange& depth,
                 const std::vector<ExtraPlanes>& extras, const Rect& window, BranchInputs* diffuse,
                 BranchInputs& specular, std::string& error,
                 const DroppedOutliers* outliers = nullptr);

/// The two branch networks of a weights file ("diffuse.*", "specular.*" tensors).
struct Model {
    nn::Net diffuse { "kpcn.diffuse" }, specular { "kpcn.specular" };
    /// False where the file's metadata says `"reads_depth": false` (a model trained with its
    /// depth always zero: the colour + albedo + normal model): the op gives it zero depth.
    bool reads_depth = true;
};
/// Builds both networks with the widths found in the file and loads them; errors name the
/// file and the tensor. `image_channels`: channels the kernels filter (3, more with extras).
bool load_model(Model& model, const std::string& path, std::string& error, int image_channels = 3);
/// One branch's network: a UNet of widths.size() ≥ 3 levels, widths[l] channels at 1/2^l of
/// the resolution (exposed for the benchmark's FLOP count and the tests).
nn::Net build_branch(const std::string& prefix, const std::vector<int>& widths, int iterations,
                     int image_channels = 3);

}  // namespace kpcn
}  // namespace mcdn
