// KPCN workers kept between calls of the op. A worker is one copy of the two branch
// networks with the storage of their inputs, layers and outputs, sized by the tile's window.
// Fresh, that memory is page faults the kernel must clear: a cost that does not shrink with
// the work a partly converged frame leaves, and a fixed cost of every call on small frames.
// A pipeline that denoises frame after frame in one process (the Python module, the format
// plugin) reuses them.
#pragma once
#include <memory>
#include <string>
#include <vector>

#include "cnn/cnn_steps.h"

namespace mcdn {
namespace kpcn {

/// What one worker keeps across its tiles (and calls).
struct Worker {
    Model model;
    BranchInputs diffuse_inputs, specular_inputs;
    std::vector<nn::Tensor> irradiance, log_specular;  // the networks' outputs
    std::string weights_key;  // the file (path, size, modification time) and channel count
};

/// An idle worker of an earlier call for the same weights file (same path, size and
/// modification time) and `image_channels`, else a new one loaded from the file; null with
/// `error` set when it cannot be loaded.
std::unique_ptr<Worker> take_worker(const std::string& path, int image_channels,
                                    std::string& error);

/// Keeps `worker` for later calls (as many as the machine has hardware threads; others are
/// freed).
void return_worker(std::unique_ptr<Worker> worker);

/// Frees every idle worker (mcdn::release_cnn_workers()).
void release_workers();

}  // namespace kpcn
}  // namespace mcdn
