// The KPCN op (Bako et al. 2017, Fig. 2), top to bottom: per network tile, read the render's
// window, split its light (§4.3) and make the branch's inputs (§5.1) for the branch network
// (§4.2); then undo the transforms and add the branches (eq. 4) on the whole frame.
#include "mcdn/cnn.h"

#include <dlfcn.h>

#include <cmath>
#include <cstdlib>

#include <tbb/task_arena.h>

#include "cnn/cnn_steps.h"
#include "cnn/extras.h"
#include "core/converged_tiles.h"
#include "core/op_prepare.h"
#include "mcdn/color.h"

namespace mcdn {

namespace {

// "<source root>/models" when the build does not say where the models are.
std::string models_dir_default()
{
#ifdef MCDN_MODELS_DIR
    return MCDN_MODELS_DIR;
#else
    std::string root = __FILE__;  // <root>/lib/src/cnn/cnn.cpp: up four components
    for (int up = 0; up < 4; ++up) {
        size_t slash = root.find_last_of("/\\");
        root = slash == std::string::npos ? std::string() : root.substr(0, slash);
    }
    return root.empty() ? std::string("models") : root + "/models";
#endif
}

/// Runs `body` on at most `nthreads` threads (0 = all): a TBB arena for our ops, and the
/// OpenMP thread count of this thread for oneDNN's convolutions (looked up at run time, as
/// only oneDNN links OpenMP; absent with a TBB-threaded oneDNN, where the arena suffices).
/// No result depends on the count: every output value is computed by one thread.
template <class Body>
bool with_threads(int nthreads, Body&& body)
{
    if (nthreads <= 0)
        return body();
    using SetThreads = void (*)(int);
    using GetThreads = int (*)();
    auto set = reinterpret_cast<SetThreads>(dlsym(RTLD_DEFAULT, "omp_set_num_threads"));
    auto get = reinterpret_cast<GetThreads>(dlsym(RTLD_DEFAULT, "omp_get_max_threads"));
    const int previous = set && get ? get() : 0;
    if (set && get)
        set(nthreads);
    bool ok = false;
    tbb::task_arena arena(nthreads);
    arena.execute([&] { ok = body(); });
    if (set && get)
        set(previous);
    return ok;
}

bool cnn_in_working_space(ImageBuf& dst, const ImageBuf& src, const CnnOptions& options,
                          ROI roi, int nthreads)
{
    AovSet aovs;
    if (!prepare_op(dst, src, options.aovs, aovs, "cnn"))
        return false;
    std::string error;
    if (!aovs.require({ Role::Color }, src.spec(), error)) {
        dst.errorfmt("cnn: {}", error);
        return false;
    }
    std::vector<ExtraPlanes> extras;
    if (denoises_extras(options.denoise_extras, src) && !read_extras(extras, dst, aovs, false, error)) {
        dst.errorfmt("cnn: {}", error);
        return false;
    }
    // mcdn/skip.h: nothing to do where every tile is converged (dst is the render).
    const ConvergedTiles converged = converged_tiles_of(dst, aovs, options.skip);
    if (converged.all())
        return true;
    kpcn::Model model;
    const std::string path = options.weights.empty() ? default_cnn_weights() : options.weights;
    const int image_channels = extras.empty() ? 3 : 3 * (2 + int(extras.size()));
    if (!kpcn::load_model(model, path, error, image_channels)) {
        dst.errorfmt("{}", error);
        return false;
    }

    // §5.1: the depth range is the one input statistic of the whole frame; everything else
    // (§4.3's split, the 34 input channels) is made per network tile from its window.
    const kpcn::DepthRange depth = kpcn::depth_range(dst, aovs);
    const int width = dst.spec().width, height = dst.spec().height;

    // §4.2: each branch's network, tiled so memory is bounded by the tile.
    nn::TileOptions tiles;
    tiles.tile_size = options.tile_size;
    nn::Tensor irradiance, log_specular;
    auto run_branch = [&](nn::Net& net, kpcn::Branch branch, nn::Tensor& result) {
        auto make_inputs = [&](const nn::Region& window, std::vector<nn::Tensor>& inputs,
                               std::string& tile_error) {
            inputs.resize(2);
            return kpcn::tile_inputs(dst, aovs, depth, branch, extras, window, inputs[0],
                                     inputs[1], tile_error);
        };
        std::vector<nn::Tensor> outputs;
        tiles.regions = network_regions(converged, net, options.tile_size);
        if (!nn::run_tiled(net, height, width, make_inputs, outputs, error, tiles)) {
            error = "cnn: '" + path + "': " + error;
            return false;
        }
        result = std::move(outputs[0]);
        return true;
    };
    kpcn::RawPlanes raw;  // the colour and the demodulation, for eq. 4
    kpcn::read_colour_and_demod(raw, dst, aovs);
    const bool ran = with_threads(nthreads, [&] {
        if (raw.split && !run_branch(model.diffuse, kpcn::Branch::diffuse, irradiance))
            return false;
        model.diffuse.give_buffers(model.specular);  // same shapes: no new memory
        return run_branch(model.specular, kpcn::Branch::specular, log_specular);
    });
    if (!ran) {
        dst.errorfmt("{}", error);
        return false;
    }

    // Eq. 4: (albedo + eps) · irradiance + exp(log specular) − 1, a channel at a time; the
    // components are kept as planes only for the extras' shares (0.4 GB each at 8K).
    kpcn::BranchResult diffuse, specular;
    diffuse.filtered = &irradiance;
    specular.filtered = &log_specular;
    const bool keep_components = !extras.empty();
    const size_t stride = size_t(log_specular.channels);
    const ROI where = output_roi(src, roi);
    const auto& colour = aovs.channels(Role::Color);
    for (int c = 0; c < 3; ++c) {
        Plane out(width, height);
        if (keep_components) {
            specular.component[c] = Plane(width, height);
            if (raw.split)
                diffuse.component[c] = Plane(width, height);
        }
        for (size_t i = 0; i < out.size(); ++i) {
            const float s = std::expm1(log_specular.data[i * stride + c]);
            const float d = raw.split ? (std::max(raw.demod[c].px[i], 0.0f) + kpcn::kAlbedoEpsilon)
                                            * irradiance.data[i * stride + c]
                                      : 0.0f;
            out.px[i] = sanitize(s + d);
            if (keep_components) {
                specular.component[c].px[i] = s;
                if (raw.split)
                    diffuse.component[c].px[i] = d;
            }
        }
        pass_through_converged(out, raw.color[c], converged);
        write_plane(dst, colour[c], out, where);
    }
    // The extras' shares of the same components: they add up to the beauty.
    kpcn::write_extras(dst, where, extras, raw.split ? &diffuse : nullptr, specular);
    pass_through_extras(dst, where, extras, converged);
    return true;
}

}  // namespace

std::string default_cnn_weights()
{
    const char* dir = std::getenv("MCDN_MODELS");
    return (dir && *dir ? std::string(dir) : models_dir_default()) + "/kpcn.mcdnw";
}

bool cnn(ImageBuf& dst, const ImageBuf& src, const CnnOptions& options, ROI roi, int nthreads)
{
    return run_in_working_space(dst, src, options.aovs, "cnn", [&](ImageBuf& d, const ImageBuf& s) {
        return cnn_in_working_space(d, s, options, roi, nthreads);
    });
}

ImageBuf cnn(const ImageBuf& src, const CnnOptions& options, ROI roi, int nthreads)
{
    ImageBuf dst;
    cnn(dst, src, options, roi, nthreads);
    return dst;
}

}  // namespace mcdn
