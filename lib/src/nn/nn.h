// Neural-network inference for the learned stages (KPCN, Bako et al. 2017; the mixing network
// of progressive denoising, Firmino et al. 2022 §4.3), in the shape of Open Image Denoise:
// a network is a short list of ops built in C++, its parameters come by name from a weights
// file written by training/ (PyTorch), and it runs on oneDNN convolutions.
//
//   Weights weights;  std::string error;
//   if (!read_weights("mix.mcdnw", weights, error)) ...           // one-line error
//   Net net("mix");
//   Value x = net.input("features", 14);
//   x = net.conv(x, "conv1", 48, 5);                              // conv1.weight [48,14,5,5]
//   Value r = net.conv(x, "res1.conv1", 48, 3);
//   r = net.conv(r, "res1.conv2", 48, 3, Activation::none);
//   x = net.add(x, r, Activation::relu);                          // residual block
//   net.output("alpha", net.conv(x, "out", 9, 3, Activation::none));
//   if (!net.load(weights, error)) ...                            // names and shapes checked
//   net.run({features}, outputs, error);                          // or run_tiled(...)
//
// Tensors are float32, batch 1, NHWC (channels fastest): oneDNN's convolutions run on it
// without reorders, and our own ops (pool, upsample, concat, kernels) read contiguous pixels.
//
// Weights file (".mcdnw"), every integer little-endian uint32, every float little-endian
// IEEE float32:
//   magic      8 bytes  "MCDNNWTS"
//   version    uint32   weights_format_version (1)
//   metadata   uint32 byte count, then that many bytes of UTF-8 JSON (free-form: network
//              name, architecture hyper-parameters, training information)
//   count      uint32   number of tensors, then for each tensor:
//     name     uint32 byte count, then the UTF-8 name ("enc1.weight", PyTorch's state_dict key)
//     rank     uint32, then rank × uint32 dims, outermost first
//     data     product(dims) × float32, row-major (last dim fastest)
//   nothing after the last tensor.
// Convolution weights are stored in PyTorch's order, OIHW: [out_channels, in_channels,
// kernel_h, kernel_w]; biases are [out_channels]. training/common/weights.py writes and
// reads the format.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "core/planar.h"

namespace mcdn {
namespace nn {

/// A float32 image, batch 1, NHWC: element (y, x, c) is data[(y * width + x) * channels + c].
struct Tensor {
    int height = 0, width = 0, channels = 0;
    std::vector<float> data;

    Tensor() = default;
    Tensor(int height, int width, int channels, float fill = 0.0f);
    size_t size() const { return size_t(height) * width * channels; }
    float* pixel(int y, int x) { return data.data() + (size_t(y) * width + x) * channels; }
    const float* pixel(int y, int x) const
    {
        return data.data() + (size_t(y) * width + x) * channels;
    }
    float& at(int y, int x, int c) { return pixel(y, x)[c]; }
    float at(int y, int x, int c) const { return pixel(y, x)[c]; }
};

// ---------------------------------------------------------------------------------------
// Weights files

constexpr uint32_t weights_format_version = 1;

/// One named parameter tensor of a weights file, dims outermost first.
struct NamedTensor {
    std::string name;
    std::vector<int> shape;
    std::vector<float> values;
};

/// The contents of a weights file. `path` is where it was read from (used in messages).
struct Weights {
    std::string path;
    uint32_t version = weights_format_version;
    std::string metadata;  // JSON, free-form
    std::vector<NamedTensor> tensors;

    /// The tensor called `name`, or nullptr.
    const NamedTensor* find(const std::string& name) const;
};

/// Reads a weights file. On failure returns false and sets `error` to one line naming the
/// file and what is wrong (wrong magic, unsupported version, truncated at tensor 'x').
bool read_weights(const std::string& path, Weights& weights, std::string& error);
/// Writes `weights` in format version weights_format_version.
bool write_weights(const std::string& path, const Weights& weights, std::string& error);
/// `name` in the models directory: $MCDN_MODELS/name when that variable is set, else
/// share/mcdenoise/models installed with the library (install_paths() in mcdn/version.h).
std::string model_file(const std::string& name);
/// A listing for humans: version, metadata and one line per tensor with its shape.
std::string describe(const Weights& weights);
/// "[48,48,3,3]"
std::string shape_string(const std::vector<int>& shape);

// ---------------------------------------------------------------------------------------
// Networks

enum class Activation { none, relu };
/// Which implementation runs the ops: oneDNN convolutions and threaded ops, or the plain
/// loops of lib/src/nn/reference.cpp that the tests check the first against.
enum class Backend { onednn, reference };

/// A value in a network under construction (the output of one op).
struct Value {
    int id = -1;
};

struct NetState;  // oneDNN primitives and reordered weights (lib/src/nn/onednn_conv.h)

/// A network: a list of ops in execution order, each reading earlier values. Build it with
/// the methods below, load() its parameters, then run() or run_tiled(). A mistake while
/// building (channel counts of add, an op on values of different scales) is remembered and
/// reported by load() and run(). Not thread-safe: run one image at a time per Net.
class Net {
public:
    enum class Op { input, conv, add, max_pool2, upsample2, concat, slice, apply_kernel };
    struct Node {
        Op op;
        std::string name;         // input/output name, or the parameter prefix of a conv
        std::vector<int> inputs;  // ids of the values read
        int channels = 0;         // channels of the result
        int kernel = 0;           // conv / apply_kernel size k (k × k)
        int first_channel = 0;    // slice
        Activation activation = Activation::none;
        int scale = 1;      // the result's pixel size in input pixels (1, 2, 4, ...)
        double radius = 0;  // receptive-field radius in input pixels (halo of tiling)
    };

    explicit Net(std::string name = "net");
    ~Net();
    Net(Net&&) noexcept;
    Net& operator=(Net&&) noexcept;

    /// A network input with `channels` channels; run() takes inputs in declaration order.
    Value input(const std::string& name, int channels);
    /// k×k convolution, stride 1, same (zero) padding, with bias and fused activation.
    /// Parameters: `<param>.weight` [out_channels, in_channels, k, k] and `<param>.bias`.
    Value conv(Value x, const std::string& param, int out_channels, int kernel,
               Activation activation = Activation::relu);
    /// a + b (residual connection), then the activation.
    Value add(Value a, Value b, Activation activation = Activation::none);
    /// 2×2 max pooling, stride 2 (the input's size must be even: see alignment()).
    Value max_pool2(Value x);
    /// 2× nearest-neighbour upsampling: out(y, x) = in(y / 2, x / 2).
    Value upsample2(Value x);
    /// Channels of `values` one after the other (torch.cat(dim=1)).
    Value concat(const std::vector<Value>& values);
    /// Channels [first, first + count) of x.
    Value slice(Value x, int first, int count);
    /// Kernel prediction (KPCN eq. 9): out(p) = Σ_q softmax(logits(p))_q image(p + q), over
    /// the k×k neighbourhood, the same weights for every channel of `image`. Logits channel
    /// t = dy·k + dx is the tap at offset (dy − k/2, dx − k/2); pixels outside the image are
    /// clamped to the edge (PyTorch: F.pad(mode="replicate") then F.unfold).
    Value apply_kernel(Value logits, Value image, int kernel);
    /// Marks x as an output; run() returns outputs in declaration order.
    void output(const std::string& name, Value x);

    const std::string& name() const { return name_; }
    const std::vector<Node>& nodes() const { return nodes_; }
    /// The nodes marked output(), in declaration order.
    const std::vector<int>& output_ids() const { return output_ids_; }
    int channels(Value x) const;
    /// Input sizes must be multiples of this (2^number of nested poolings).
    int alignment() const;
    /// Receptive-field radius of the outputs in input pixels, rounded up (tiling halo).
    int receptive_radius() const;
    /// Every parameter the network expects with its shape, "conv1.weight [48,14,5,5]" lines.
    std::string expected_parameters() const;

    /// Takes every conv's parameters from `weights`, checking names and shapes; a tensor of
    /// the file that no op uses is an error too (like torch's strict load_state_dict).
    bool load(const Weights& weights, std::string& error);
    bool loaded() const { return loaded_; }

    /// Runs on whole tensors, one per input(), all of one size (a multiple of alignment()):
    /// the steps decided when its state was made (nn/net_plan.h), in order.
    bool run(const std::vector<Tensor>& inputs, std::vector<Tensor>& outputs, std::string& error,
             Backend backend = Backend::onednn);
    /// Hands the buffers this network keeps between runs to `other`, which runs next (the
    /// two branches of KPCN): fresh memory is costly to touch (page faults), reused is not.
    void give_buffers(Net& other);

private:
    bool check_inputs(const std::vector<Tensor>& inputs, std::string& error) const;
    Value add_node(Node node);
    bool check(Value x, const char* op);
    void make_state();
    void fail(const std::string& message);

    std::string name_;
    std::vector<Node> nodes_;
    std::vector<int> input_ids_;
    std::vector<int> output_ids_;
    std::vector<std::string> output_names_;
    std::string build_error_;
    bool loaded_ = false;
    // Parameters per node (empty for parameter-free ops), OIHW weights then bias.
    std::vector<std::vector<float>> weights_, biases_;
    std::unique_ptr<NetState> state_;

    friend struct NetRunner;
};

struct TileOptions {
    /// Output tile side in pixels (rounded up to alignment()); memory grows with
    /// (tile_size + 2 × halo)² × widest layer; every tile recomputes its halo, and a
    /// tile's buffers are reused by the next (Net::run), so fewer, larger tiles are faster.
    int tile_size = 512;
    Backend backend = Backend::onednn;
    /// When not empty, only these output rectangles are computed, each as one tile with its
    /// halo (x0 and y0 multiples of alignment(); sides at most tile_size for bounded memory);
    /// the outputs are 0 elsewhere. Used to skip converged tiles (mcdn/skip.h).
    std::vector<Rect> regions;
    /// Without regions: the grid of cores that split the image evenly, chosen so that the
    /// windows add up to the fewest pixels (the least halo computed again) while each holds
    /// at most (tile_size + 2 × halo)² — the memory of a square tile's window; 1080p at tile
    /// 1024 (halo 96): two windows of 1056 × 1080 where square tiles make four, 1.10× the
    /// image's pixels against 1.30×. Else square cores of tile_size from the corner.
    bool balanced = false;
};

/// One tile of a tiled run: the output rectangle it owns (`core`, aligned; it may reach past
/// the image into the extension below) and the input `window` computed for it (the core
/// grown by the halo, clipped to the extended image).
struct Tile {
    Rect core, window;
};

/// The tiles run_tiled computes for a height × width image, largest window first (so the
/// buffers of a Net's first tile hold every later tile's values). False and `error` for
/// regions that do not start at multiples of net.alignment().
bool plan_tiles(const Net& net, int height, int width, const TileOptions& options,
                std::vector<Tile>& tiles, std::string& error);

/// Runs work(index, worker) for every index in [0, count), in order on this thread when
/// workers <= 1; else on `workers` OpenMP threads, indices handed out one at a time, each
/// worker numbered in [0, workers) so it can keep its own Net and buffers (a Net runs one
/// image at a time). Inside, convolutions and ops run on their worker alone. False from
/// any call stops the rest and is returned.
bool for_each_tile(int count, int workers, const std::function<bool(int index, int worker)>& work);

/// The OpenMP threads of this thread's parallel regions (1 without OpenMP).
int max_threads();

/// Runs `net` over whole images tile by tile; each tile is computed with a halo of
/// receptive_radius() pixels (rounded to alignment()) so the result equals an untiled run.
/// Any image size is accepted: the image is extended to a multiple of alignment() by
/// repeating its last row and column, and the outputs are cropped back.
bool run_tiled(Net& net, const std::vector<Tensor>& inputs, std::vector<Tensor>& outputs,
               std::string& error, const TileOptions& options = {});

/// Makes one tile's inputs, one tensor per input() into `inputs` (reshaped; their storage
/// is kept from the last tile): the window [x0, x1) × [y0, y1) of the image extended as
/// above (rows and columns past the image repeat its last ones). False stops the run.
using TileInputs =
    std::function<bool(const Rect& window, std::vector<Tensor>& inputs, std::string& error)>;

/// run_tiled on a height × width image whose inputs are made tile by tile: no whole-image
/// input exists, so memory is bounded by the tile (KPCN's 34 input channels are ~10x its
/// image). The result is that of run_tiled on the whole inputs make_inputs would cut from.
bool run_tiled(Net& net, int height, int width, const TileInputs& make_inputs,
               std::vector<Tensor>& outputs, std::string& error, const TileOptions& options = {});

}  // namespace nn
}  // namespace mcdn
