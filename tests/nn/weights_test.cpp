// The weights file: round trip, the file Python writes, and one-line errors that name the
// file, the tensor and both shapes.
#include <fstream>

#include "nn_test_util.h"

using namespace nn_test;

namespace {

std::string read_bytes(const std::string& path)
{
    std::ifstream f(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
}

void write_bytes(const std::string& path, const std::string& bytes)
{
    std::ofstream(path, std::ios::binary).write(bytes.data(), std::streamsize(bytes.size()));
}

Weights small_weights()
{
    Weights w;
    w.metadata = R"({"network": "mix", "channels": 48})";
    w.tensors.push_back({ "conv1.weight", { 2, 1, 3, 3 }, std::vector<float>(18, 0.5f) });
    w.tensors.push_back({ "conv1.bias", { 2 }, { -1.0f, 2.5f } });
    return w;
}

/// The one-line error of reading `bytes` as a weights file.
std::string read_error(const std::string& dir, const std::string& bytes)
{
    const std::string path = dir + "/bad.mcdnw";
    write_bytes(path, bytes);
    Weights w;
    std::string error;
    EXPECT_FALSE(read_weights(path, w, error));
    EXPECT_EQ(error.find('\n'), std::string::npos) << error;
    EXPECT_EQ(error.rfind(path + ": ", 0), 0u) << "the error names the file: " << error;
    return error;
}

TEST(NnWeights, RoundTrip)
{
    const std::string dir = mcdn_test::temp_dir("nn_weights");
    std::string error;
    ASSERT_TRUE(write_weights(dir + "/w.mcdnw", small_weights(), error)) << error;
    Weights w;
    ASSERT_TRUE(read_weights(dir + "/w.mcdnw", w, error)) << error;
    EXPECT_EQ(w.version, weights_format_version);
    EXPECT_EQ(w.metadata, small_weights().metadata);
    ASSERT_EQ(w.tensors.size(), 2u);
    EXPECT_EQ(w.find("conv1.bias")->values, std::vector<float>({ -1.0f, 2.5f }));
    EXPECT_EQ(w.find("conv1.weight")->shape, std::vector<int>({ 2, 1, 3, 3 }));
    EXPECT_EQ(w.find("nothing"), nullptr);
    EXPECT_NE(describe(w).find("conv1.weight [2,1,3,3]"), std::string::npos) << describe(w);
}

TEST(NnWeights, ReadsWhatPythonWrites)
{
    Weights w;
    std::string error;
    ASSERT_TRUE(read_weights(mcdn_test::test_data("nn/tiny_net.mcdnw"), w, error)) << error;
    EXPECT_NE(w.metadata.find("\"network\": \"tiny_net\""), std::string::npos) << w.metadata;
    ASSERT_NE(w.find("res.conv2.weight"), nullptr);
    EXPECT_EQ(w.find("res.conv2.weight")->shape, std::vector<int>({ 24, 24, 3, 3 }));
}

TEST(NnWeights, CorruptFilesAreOneLineErrors)
{
    const std::string dir = mcdn_test::temp_dir("nn_weights_bad");
    std::string error;
    ASSERT_TRUE(write_weights(dir + "/good.mcdnw", small_weights(), error)) << error;
    const std::string good = read_bytes(dir + "/good.mcdnw");

    EXPECT_NE(read_error(dir, "GIF89a" + good.substr(6)).find("not a mcdenoise weights file"),
              std::string::npos);
    std::string version_2 = good;
    version_2[8] = 2;
    EXPECT_NE(
        read_error(dir, version_2).find("weights format version 2, this build reads version 1"),
        std::string::npos);
    const std::string truncated = read_error(dir, good.substr(0, good.size() - 5));
    EXPECT_NE(truncated.find("truncated in the data of tensor 'conv1.bias' [2]"), std::string::npos)
        << truncated;
    EXPECT_NE(read_error(dir, good.substr(0, 10)).find("truncated in the header"),
              std::string::npos);
    EXPECT_NE(read_error(dir, good + "xx").find("2 unexpected bytes after the last tensor"),
              std::string::npos);

    Weights w;
    EXPECT_FALSE(read_weights(dir + "/absent.mcdnw", w, error));
    EXPECT_NE(error.find("absent.mcdnw: no such file"), std::string::npos) << error;
}

Net mix_like()
{
    Net net("mix");
    Value x = net.input("features", 1);
    net.output("y", net.conv(x, "conv1", 2, 3));
    return net;
}

TEST(NnWeights, LoadChecksNamesAndShapes)
{
    std::string error;
    Net net = mix_like();
    Weights w = small_weights();
    w.path = "mix.mcdnw";
    EXPECT_TRUE(net.load(w, error)) << error;
    EXPECT_EQ(net.expected_parameters(), "conv1.weight [2,1,3,3]\nconv1.bias [2]\n");

    Weights wrong_shape = w;
    wrong_shape.tensors[0].shape = { 2, 1, 5, 5 };
    EXPECT_FALSE(net.load(wrong_shape, error));
    EXPECT_EQ(error, "mix.mcdnw: tensor 'conv1.weight' has shape [2,1,5,5], the network 'mix' "
                     "expects [2,1,3,3]");

    Weights missing = w;
    missing.tensors.erase(missing.tensors.begin() + 1);
    EXPECT_FALSE(net.load(missing, error));
    EXPECT_EQ(
        error.rfind("mix.mcdnw: tensor 'conv1.bias' is missing, the network 'mix' expects [2]", 0),
        0u)
        << error;

    Weights extra = w;
    extra.tensors.push_back({ "conv2.weight", { 1 }, { 0.0f } });
    EXPECT_FALSE(net.load(extra, error));
    EXPECT_NE(error.find("tensor 'conv2.weight' [1] is not used by the network 'mix'"),
              std::string::npos)
        << error;

    std::vector<Tensor> out;
    EXPECT_FALSE(net.run({ Tensor(4, 4, 1) }, out, error));
    EXPECT_NE(error.find("run before load()"), std::string::npos) << error;
}

TEST(NnWeights, BuildMistakesAreReported)
{
    Net net("broken");
    Value x = net.input("x", 4);
    Value y = net.conv(x, "c", 8, 3);
    net.output("z", net.add(x, y));  // 4 + 8 channels
    std::string error;
    EXPECT_FALSE(net.load(Weights(), error));
    EXPECT_EQ(error, "network 'broken': add of values with 4 and 8 channels at scales 1/1 and 1/1 "
                     "(they must match)");

    Net odd("odd");
    Value p = odd.max_pool2(odd.input("x", 1));
    odd.output("p", p);
    ASSERT_TRUE(odd.load(Weights(), error)) << error;
    std::vector<Tensor> out;
    EXPECT_FALSE(odd.run({ Tensor(5, 4, 1) }, out, error));
    EXPECT_NE(error.find("sizes must be multiples of 2"), std::string::npos) << error;
}

}  // namespace
