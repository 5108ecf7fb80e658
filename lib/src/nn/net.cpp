// Net: the builder (shape, scale and receptive field of every value, checked as the
// network is written) and load() (parameters by name, shapes checked). How it runs:
// net_plan.cpp (decided once) and net_run.cpp (the loop).
#include <algorithm>
#include <cmath>

#include "nn/onednn_conv.h"
#include "nn/ops.h"

namespace mcdn {
namespace nn {

Net::Net(std::string name) : name_(std::move(name)) { }
Net::~Net() = default;
Net::Net(Net&&) noexcept = default;
Net& Net::operator=(Net&&) noexcept = default;

void Net::fail(const std::string& message)
{
    if (build_error_.empty())  // the first mistake explains the rest
        build_error_ = "network '" + name_ + "': " + message;
}

bool Net::check(Value x, const char* op)
{
    if (x.id >= 0 && x.id < int(nodes_.size()))
        return true;
    fail(std::string(op) + " reads a value that is not from this network");
    return false;
}

Value Net::add_node(Node node)
{
    loaded_ = false;  // the parameters no longer match the graph
    nodes_.push_back(std::move(node));
    return Value { int(nodes_.size()) - 1 };
}

int Net::channels(Value x) const
{
    return x.id >= 0 && x.id < int(nodes_.size()) ? nodes_[x.id].channels : 0;
}

Value Net::input(const std::string& name, int channels)
{
    if (channels <= 0)
        fail("input '" + name + "' needs at least one channel");
    Node node { Op::input, name, {}, channels };
    input_ids_.push_back(int(nodes_.size()));
    return add_node(node);
}

Value Net::conv(Value x, const std::string& param, int out_channels, int kernel,
                Activation activation)
{
    if (!check(x, "conv"))
        return x;
    if (kernel <= 0 || kernel % 2 == 0 || out_channels <= 0)
        fail("conv '" + param + "' needs an odd kernel size and output channels (same padding)");
    const Node& in = nodes_[x.id];
    Node node { Op::conv, param, { x.id }, out_channels, kernel };
    node.activation = activation;
    node.scale = in.scale;
    node.radius = in.radius + (kernel / 2) * in.scale;
    return add_node(node);
}

Value Net::add(Value a, Value b, Activation activation)
{
    if (!check(a, "add") || !check(b, "add"))
        return a;
    const Node &na = nodes_[a.id], &nb = nodes_[b.id];
    if (na.channels != nb.channels || na.scale != nb.scale)
        fail("add of values with " + std::to_string(na.channels) + " and "
             + std::to_string(nb.channels) + " channels at scales 1/" + std::to_string(na.scale)
             + " and 1/" + std::to_string(nb.scale) + " (they must match)");
    Node node { Op::add, "", { a.id, b.id }, na.channels };
    node.activation = activation;
    node.scale = na.scale;
    node.radius = std::max(na.radius, nb.radius);
    return add_node(node);
}

Value Net::max_pool2(Value x)
{
    if (!check(x, "max_pool2"))
        return x;
    const Node& in = nodes_[x.id];
    Node node { Op::max_pool2, "", { x.id }, in.channels };
    node.scale = in.scale * 2;
    node.radius = in.radius + in.scale;  // the 2×2 window reaches one input pixel further
    return add_node(node);
}

Value Net::upsample2(Value x)
{
    if (!check(x, "upsample2"))
        return x;
    const Node& in = nodes_[x.id];
    if (in.scale < 2)
        fail("upsample2 above the input resolution (not supported by tiling)");
    Node node { Op::upsample2, "", { x.id }, in.channels };
    node.scale = std::max(in.scale / 2, 1);
    node.radius = in.radius + node.scale;  // a pixel copies a neighbour up to 1 step away
    return add_node(node);
}

Value Net::concat(const std::vector<Value>& values)
{
    if (values.empty()) {
        fail("concat of nothing");
        return Value {};
    }
    Node node { Op::concat, "", {}, 0 };
    for (Value v : values) {
        if (!check(v, "concat"))
            return v;
        const Node& in = nodes_[v.id];
        if (in.scale != nodes_[values[0].id].scale)
            fail("concat of values at different scales (1/" + std::to_string(in.scale) + " and 1/"
                 + std::to_string(nodes_[values[0].id].scale) + ")");
        node.inputs.push_back(v.id);
        node.channels += in.channels;
        node.scale = in.scale;
        node.radius = std::max(node.radius, in.radius);
    }
    return add_node(node);
}

Value Net::slice(Value x, int first, int count)
{
    if (!check(x, "slice"))
        return x;
    const Node& in = nodes_[x.id];
    if (first < 0 || count <= 0 || first + count > in.channels)
        fail("slice [" + std::to_string(first) + ", " + std::to_string(first + count)
             + ") of a value with " + std::to_string(in.channels) + " channels");
    Node node { Op::slice, "", { x.id }, count };
    node.first_channel = first;
    node.scale = in.scale;
    node.radius = in.radius;
    return add_node(node);
}

Value Net::apply_kernel(Value logits, Value image, int kernel)
{
    if (!check(logits, "apply_kernel") || !check(image, "apply_kernel"))
        return image;
    const Node &nl = nodes_[logits.id], &ni = nodes_[image.id];
    if (kernel <= 0 || kernel % 2 == 0 || nl.channels != kernel * kernel)
        fail("apply_kernel of size " + std::to_string(kernel) + " needs an odd size and "
             + std::to_string(kernel * kernel) + " logit channels, got "
             + std::to_string(nl.channels));
    if (nl.scale != ni.scale)
        fail("apply_kernel with logits and image at different scales");
    Node node { Op::apply_kernel, "", { logits.id, image.id }, ni.channels, kernel };
    node.scale = ni.scale;
    node.radius = std::max(nl.radius, ni.radius + (kernel / 2) * ni.scale);
    return add_node(node);
}

void Net::output(const std::string& name, Value x)
{
    if (!check(x, "output"))
        return;
    output_ids_.push_back(x.id);
    output_names_.push_back(name);
}

int Net::alignment() const
{
    int alignment = 1;
    for (const Node& node : nodes_)
        alignment = std::max(alignment, node.scale);
    return alignment;
}

int Net::receptive_radius() const
{
    double radius = 0;
    for (int id : output_ids_)
        radius = std::max(radius, nodes_[id].radius);
    return int(std::ceil(radius));
}

std::string Net::expected_parameters() const
{
    std::string list;
    for (const Node& node : nodes_)
        if (node.op == Op::conv) {
            const int in_channels = nodes_[node.inputs[0]].channels;
            list += node.name + ".weight "
                    + shape_string({ node.channels, in_channels, node.kernel, node.kernel }) + "\n"
                    + node.name + ".bias " + shape_string({ node.channels }) + "\n";
        }
    return list;
}

// ---------------------------------------------------------------------------------------
// load

namespace {

/// The tensor `name` of `weights` with exactly `shape`, or nullptr and a one-line error.
const NamedTensor* find_tensor(const Weights& weights, const std::string& net_name,
                               const std::string& name, const std::vector<int>& shape,
                               std::string& error)
{
    const std::string file = weights.path.empty() ? "weights" : weights.path;
    const NamedTensor* tensor = weights.find(name);
    if (!tensor) {
        error = file + ": tensor '" + name + "' is missing, the network '" + net_name + "' expects "
                + shape_string(shape) + " (the file has " + std::to_string(weights.tensors.size())
                + " tensors: is it for this network?)";
        return nullptr;
    }
    if (tensor->shape != shape) {
        error = file + ": tensor '" + name + "' has shape " + shape_string(tensor->shape)
                + ", the network '" + net_name + "' expects " + shape_string(shape);
        return nullptr;
    }
    return tensor;
}

}  // namespace

bool Net::load(const Weights& weights, std::string& error)
{
    loaded_ = false;
    state_.reset();
    if (!build_error_.empty()) {
        error = build_error_;
        return false;
    }
    weights_.assign(nodes_.size(), {});
    biases_.assign(nodes_.size(), {});
    std::vector<std::string> used;
    for (size_t id = 0; id < nodes_.size(); ++id) {
        const Node& node = nodes_[id];
        if (node.op != Op::conv)
            continue;
        const int in_channels = nodes_[node.inputs[0]].channels;
        const std::string weight_name = node.name + ".weight", bias_name = node.name + ".bias";
        const NamedTensor* w =
            find_tensor(weights, name_, weight_name,
                        { node.channels, in_channels, node.kernel, node.kernel }, error);
        const NamedTensor* b =
            w ? find_tensor(weights, name_, bias_name, { node.channels }, error) : nullptr;
        if (!b)
            return false;
        weights_[id] = w->values;
        biases_[id] = b->values;
        used.push_back(weight_name);
        used.push_back(bias_name);
    }
    // Like torch's strict load_state_dict: a tensor nobody reads means another architecture.
    for (const NamedTensor& t : weights.tensors)
        if (std::find(used.begin(), used.end(), t.name) == used.end()) {
            error = (weights.path.empty() ? "weights" : weights.path) + ": tensor '" + t.name + "' "
                    + shape_string(t.shape) + " is not used by the network '" + name_
                    + "' (is the file for another architecture?)";
            return false;
        }
    loaded_ = true;
    return true;
}

}  // namespace nn
}  // namespace mcdn
