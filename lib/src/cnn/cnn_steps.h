// The steps of the KPCN op (lib/src/cnn/cnn.cpp), exposed for the tests: the raw planes of
// the render (the diffuse/specular split, KPCN §4.3), the network inputs of a branch (§5.1),
// and the two branch networks (§4.2). training/cnn/{data,model}.py compute the same.
#pragma once

#include <string>

#include "core/planar.h"
#include "mcdn/aov.h"
#include "mcdn/nn.h"

namespace mcdn {
namespace kpcn {

constexpr const char* kInputLayout = "kpcn-cpu-1";  // model.py INPUT_LAYOUT
constexpr int kInputChannels = 34;
constexpr float kAlbedoEpsilon = 0.00316f;          // §4.3
constexpr float kInputLimit = 1e3f;                 // network inputs clamped to +-this
constexpr int kKernel = 5;                          // each reconstruction step is 5×5

/// What the op reads, one plane per channel, sanitized (finite). Depth is unscaled until
/// scale_depth(). Without a split, diffuse is zero and specular is the colour.
struct RawPlanes {
    bool split = false;
    Plane color[3], color_var[3];
    Plane diffuse[3], diffuse_var[3];
    Plane specular[3], specular_var[3];
    Plane demod[3];  // the albedo divided out of the diffuse part (DiffCol)
    Plane albedo[3], albedo_var[3], normal[3], normal_var[3], depth, depth_var;
    int width() const { return color[0].width; }
    int height() const { return color[0].height; }
};

/// Reads the raw planes (training/cnn/data.py load_render). Component variances: the delta
/// method over the passes, Var[C (D + I)] ~ C² (Var D + Var I) + (D + I)² Var C, passes
/// taken as independent; where a pass has no variance channel, the colour's variance.
bool read_raw_planes(RawPlanes& raw, const ImageBuf& src, const AovSet& aovs,
                     std::string& error);

/// §5.1: depth scaled linearly to [0, 1] over the frame (its variance by the same factor²).
void scale_depth(RawPlanes& raw);

enum class Branch { diffuse, specular };

/// The 34 network input channels of a branch (layout in training/cnn/model.py) and the image
/// its kernels filter: irradiance = diffuse / (demod + eps), or log(1 + specular).
void branch_inputs(const RawPlanes& raw, Branch branch, nn::Tensor& features, nn::Tensor& image);

/// The two branch networks of a weights file ("diffuse.*", "specular.*" tensors).
struct Model {
    nn::Net diffuse{ "kpcn.diffuse" }, specular{ "kpcn.specular" };
};
/// Builds both networks with the widths found in the file and loads them; errors name the
/// file and the tensor. `image_channels`: channels the kernels filter (3, more with extras).
bool load_model(Model& model, const std::string& path, std::string& error,
                int image_channels = 3);
/// One branch's network (exposed for the benchmark's FLOP count and the tests).
nn::Net build_branch(const std::string& prefix, int width1, int width2, int width3,
                     int iterations, int image_channels = 3);

}  // namespace kpcn
}  // namespace mcdn
