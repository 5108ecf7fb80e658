// The storage plan (nn/net_plan.h): values alive at the same time never share a slot, each
// slot holds every value given to it, and the slots add up to little more than the network's
// widest moment, which is what a tile of the network then costs in memory.
#include "nn/net_plan.h"
#include "nn_test_util.h"

using namespace nn_test;

namespace {

/// OIDN's UNet's shape (its published architecture: five levels, skips from the pools and
/// the input) with a residual block and a kernel head, so that every kind of step is planned.
Net unet(std::vector<int>& outputs)
{
    Net net("unet");
    Value x = net.input("input", 9);
    Value e0 = net.conv(x, "enc_conv0", 32, 3);
    Value p1 = net.max_pool2(net.conv(e0, "enc_conv1", 32, 3));
    Value p2 = net.max_pool2(net.conv(p1, "enc_conv2", 48, 3));
    Value p3 = net.max_pool2(net.conv(p2, "enc_conv3", 64, 3));
    Value p4 = net.max_pool2(net.conv(p3, "enc_conv4", 80, 3));
    Value e5 = net.conv(net.conv(p4, "enc_conv5a", 96, 3), "enc_conv5b", 96, 3);
    Value r = net.add(e5, net.conv(e5, "residual", 96, 3, Activation::none), Activation::relu);
    Value d4 = net.conv(net.conv(net.concat({ net.upsample2(r), p3 }), "dec_conv4a", 112, 3),
                        "dec_conv4b", 112, 3);
    Value d3 = net.conv(net.conv(net.concat({ net.upsample2(d4), p2 }), "dec_conv3a", 96, 3),
                        "dec_conv3b", 96, 3);
    Value d2 = net.conv(net.conv(net.concat({ net.upsample2(d3), p1 }), "dec_conv2a", 64, 3),
                        "dec_conv2b", 64, 3);
    Value d1 = net.conv(net.conv(net.concat({ net.upsample2(d2), x }), "dec_conv1a", 64, 3),
                        "dec_conv1b", 32, 3);
    Value logits = net.conv(d1, "kernel", 9, 1, Activation::none);
    Value out = net.apply_kernel(net.slice(logits, 0, 9), net.slice(x, 0, 3), 3);
    net.output("output", out);
    outputs = { out.id };
    return net;
}

double floats_per_pixel(const Net::Node& node)
{
    return double(node.channels) / (double(node.scale) * node.scale);
}

}  // namespace

TEST(NnPlan, LiveValuesNeverShareASlotAndTheSlotsStayNearThePeak)
{
    std::vector<int> outputs;
    const Net net = unet(outputs);
    const std::vector<Net::Node>& nodes = net.nodes();
    for (bool fuse : { true, false }) {
        std::vector<Step> steps = plan_steps(nodes, outputs, fuse);
        const StoragePlan plan = plan_storage(steps, nodes, outputs);
        // Replay the run: who holds each slot, and how many floats a pixel are alive.
        std::vector<int> holder(plan.slot_floats.size(), -1);
        std::vector<int> slot_of(nodes.size(), -1);
        double live = 0, peak = 0;
        for (const Step& step : steps) {
            if (step.kind == Step::Kind::take
                || (step.kind == Step::Kind::conv_sum && step.in_place)) {
                slot_of[step.id] = slot_of[step.other];
                slot_of[step.other] = -1;
                if (slot_of[step.id] >= 0)
                    holder[slot_of[step.id]] = step.id;
            } else if (computes_into_storage(step)) {
                ASSERT_GE(step.slot, 0) << nodes[step.id].name;
                ASSERT_LT(step.slot, int(holder.size()));
                EXPECT_EQ(holder[step.slot], -1)
                    << nodes[step.id].name << " (fuse " << fuse << ") into the slot of "
                    << nodes[holder[step.slot]].name << ", still alive";
                EXPECT_GE(plan.slot_floats[step.slot], floats_per_pixel(nodes[step.id]));
                holder[step.slot] = step.id;
                slot_of[step.id] = step.slot;
                live += floats_per_pixel(nodes[step.id]);
                // An upconv's phase scratch: alive during the step alone, in a slot of its own.
                double scratch = 0;
                if (step.kind == Step::Kind::upconv) {
                    EXPECT_TRUE(fuse);
                    ASSERT_GE(step.scratch_slot, 0);
                    EXPECT_NE(step.scratch_slot, step.slot);
                    EXPECT_EQ(holder[step.scratch_slot], -1)
                        << nodes[holder[step.scratch_slot]].name;
                    scratch = floats_per_pixel(nodes[step.id]) / 4;
                    EXPECT_GE(plan.slot_floats[step.scratch_slot], scratch);
                }
                peak = std::max(peak, live + scratch);
            } else {
                EXPECT_EQ(step.slot, -1);
            }
            for (int k : step.free_after)
                if (slot_of[k] >= 0) {
                    holder[slot_of[k]] = -1;
                    slot_of[k] = -1;
                    live -= floats_per_pixel(nodes[k]);
                }
        }
        // Every decoder conv of concat(upsample2(x), skip) reads its two parts: none is made.
        const auto count = [&](Step::Kind kind) {
            return std::count_if(steps.begin(), steps.end(),
                                 [&](const Step& step) { return step.kind == kind; });
        };
        EXPECT_EQ(count(Step::Kind::upconv), fuse ? 4 : 0);
        EXPECT_EQ(count(Step::Kind::concat), fuse ? 0 : 4);
        ASSERT_EQ(plan.output_slot.size(), 1u);
        EXPECT_EQ(plan.output_slot[0], slot_of[outputs[0]]);
        double total = 0;
        for (double floats : plan.slot_floats)
            total += floats;
        // A pool that only reuses buffers that already fit keeps ~250 floats a pixel for this
        // network; the widest moment (the last concat and the conv reading it; fused, the
        // conv's two inputs, its phase scratch and output) is ~140.
        EXPECT_LE(total, 1.35 * peak)
            << "fuse " << fuse << ": slots " << total << ", peak " << peak;
    }
}

TEST(NnPlan, RunsOfAnySizeInAnyOrderGiveTheSameResult)
{
    std::vector<int> outputs;
    Net net = unet(outputs);
    std::string error;
    ASSERT_TRUE(net.load(random_weights(net, 11), error)) << error;
    const Tensor small = random_tensor(32, 48, 9, 12), large = random_tensor(64, 80, 9, 13);
    std::vector<Tensor> first, again, big;
    ASSERT_TRUE(net.run({ small }, first, error)) << error;
    ASSERT_TRUE(net.run({ large }, big, error)) << error;  // slots grown under the outputs
    std::vector<Tensor> handed_back = big;
    ASSERT_TRUE(net.run({ small }, handed_back, error)) << error;
    EXPECT_EQ(handed_back[0].data, first[0].data);
    Net fresh = unet(outputs);
    ASSERT_TRUE(fresh.load(random_weights(fresh, 11), error)) << error;
    ASSERT_TRUE(fresh.run({ large }, again, error)) << error;
    EXPECT_EQ(again[0].data, big[0].data);
}
