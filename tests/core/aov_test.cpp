// AOV channel sets: presets, overrides and the errors that tell a user what is missing.
#include "mcdn/aov.h"
#include "mcdn/io.h"

#include "fixtures.h"
#include "mcdn_test.h"

using mcdn_test::box16;

using namespace mcdn;

namespace {

ImageBuf named(const std::vector<std::string>& names)
{
    return mcdn_test::make_image(4, 3, names, [](int x, int y, int c) { return 0.1f * c; });
}

}  // namespace

TEST(Aov, CyclesPresetResolvesEveryFaceOfTheBoxRender)
{
    ImageBuf merged = box16();
    AovSet set;
    std::string error;
    ASSERT_TRUE(resolve_aovs(set, AovSpec(), merged.spec(), error)) << error;
    EXPECT_EQ(set.names(Role::Color),
              (std::vector<std::string> { "ViewLayer.Combined.R", "ViewLayer.Combined.G",
                                          "ViewLayer.Combined.B" }));
    EXPECT_EQ(set.names(Role::ColorVariance)[0], "variance.ViewLayer.Combined.R");
    EXPECT_EQ(set.names(Role::AlbedoA)[2], "A.ViewLayer.Denoising Albedo.B");
    EXPECT_EQ(set.names(Role::NormalB)[1], "B.ViewLayer.Denoising Normal.Y");
    EXPECT_EQ(set.names(Role::Depth)[0], "ViewLayer.Denoising Depth.Z");
    EXPECT_EQ(set.names(Role::DepthVariance)[0], "variance.ViewLayer.Denoising Depth.Z");
    EXPECT_FALSE(set.has(Role::Visibility));
    EXPECT_TRUE(set.has_component_split());
    for (Role r : { Role::Color, Role::ColorVariance, Role::ColorA, Role::ColorB })
        for (size_t i = 0; i < set.channels(r).size(); ++i)
            EXPECT_EQ(merged.spec().channelnames[set.channels(r)[i]], set.names(r)[i]);
    EXPECT_TRUE(set.require({ Role::Color, Role::ColorVariance, Role::ColorA, Role::ColorB,
                              Role::Albedo, Role::Normal, Role::Depth },
                            merged.spec(), error))
        << error;
}

TEST(Aov, CyclesPresetFindsAnyViewLayerName)
{
    ImageBuf buf = named({ "Shot Layer.Combined.R", "Shot Layer.Combined.G",
                           "Shot Layer.Combined.B", "Shot Layer.Denoising Depth.Z" });
    AovSet set;
    std::string error;
    ASSERT_TRUE(resolve_aovs(set, AovSpec(), buf.spec(), error)) << error;
    EXPECT_EQ(set.channels(Role::Color), (std::vector<int> { 0, 1, 2 }));
    EXPECT_EQ(set.channels(Role::Depth), (std::vector<int> { 3 }));
}

TEST(Aov, CyclesLightGroupsBecomeExtras)
{
    ImageBuf buf = named({ "V.Combined.R", "V.Combined.G", "V.Combined.B", "V.Combined_key.R",
                           "V.Combined_key.G", "V.Combined_key.B" });
    AovSet set;
    std::string error;
    ASSERT_TRUE(resolve_aovs(set, AovSpec(), buf.spec(), error)) << error;
    ASSERT_EQ(set.extras().size(), 1u);
    EXPECT_EQ(set.extras()[0].name, "V.Combined_key");
    EXPECT_EQ(set.extras()[0].channels, (std::vector<int> { 3, 4, 5 }));
}

TEST(Aov, GenericPresetReadsOneMultilayerFile)
{
    ImageBuf buf = named({ "R", "G", "B", "variance.R", "variance.G", "variance.B", "A.R", "A.G",
                           "A.B", "albedo.R", "albedo.G", "albedo.B", "N.X", "N.Y", "N.Z", "Z" });
    AovSpec spec;
    spec.preset = "generic";
    AovSet set;
    std::string error;
    ASSERT_TRUE(resolve_aovs(set, spec, buf.spec(), error)) << error;
    EXPECT_EQ(set.channels(Role::ColorVariance), (std::vector<int> { 3, 4, 5 }));
    EXPECT_EQ(set.channels(Role::ColorA), (std::vector<int> { 6, 7, 8 }));
    EXPECT_FALSE(set.has(Role::ColorB));
    EXPECT_EQ(set.channels(Role::Normal), (std::vector<int> { 12, 13, 14 }));
    EXPECT_EQ(set.channels(Role::Depth), (std::vector<int> { 15 }));
}

TEST(Aov, TungstenDirectoryReadsIntoTheGenericLayout)
{
    ImageBuf merged;
    ASSERT_TRUE(read_inputs(merged, { { mcdn_test::test_data("cornell20"), InputKind::Mean } }))
        << merged.geterror();
    AovSpec spec;
    spec.preset = "tungsten";
    AovSet set;
    std::string error;
    ASSERT_TRUE(resolve_aovs(set, spec, merged.spec(), error)) << error;
    for (Role base : { Role::Color, Role::Albedo, Role::Normal, Role::Depth })
        for (Face face : { Face::Mean, Face::Variance, Face::HalfA, Face::HalfB })
            EXPECT_TRUE(set.has(face_of(base, face))) << role_name(face_of(base, face));
    EXPECT_EQ(set.names(Role::NormalVariance)[0], "variance.N.X");
    EXPECT_EQ(merged.spec().width, 64);
}

TEST(Aov, OverrideReplacesARoleAndItsFacesFollow)
{
    ImageBuf buf = named({ "beauty.R", "beauty.G", "beauty.B", "variance.beauty.R",
                           "variance.beauty.G", "variance.beauty.B" });
    AovSpec spec;
    spec.preset = "generic";
    std::string error;
    ASSERT_TRUE(spec.parse_override("color=beauty.R,beauty.G,beauty.B", error)) << error;
    AovSet set;
    ASSERT_TRUE(resolve_aovs(set, spec, buf.spec(), error)) << error;
    EXPECT_EQ(set.channels(Role::Color), (std::vector<int> { 0, 1, 2 }));
    EXPECT_EQ(set.channels(Role::ColorVariance), (std::vector<int> { 3, 4, 5 }));
}

TEST(Aov, BadOverridesAreErrorsThatSayWhy)
{
    AovSpec spec;
    std::string error;
    EXPECT_FALSE(spec.parse_override("colour=R,G,B", error));
    EXPECT_NE(error.find("unknown aov role 'colour'"), std::string::npos) << error;
    EXPECT_FALSE(spec.parse_override("depth=Z,Y", error));
    EXPECT_NE(error.find("takes 1 channel"), std::string::npos) << error;
    EXPECT_FALSE(spec.parse_override("color", error));

    ImageBuf buf = named({ "R", "G", "B" });
    spec.preset = "generic";
    ASSERT_TRUE(spec.parse_override("albedo=alb.R,alb.G,alb.B", error));
    AovSet set;
    EXPECT_FALSE(resolve_aovs(set, spec, buf.spec(), error));
    EXPECT_NE(error.find("alb.R"), std::string::npos) << error;
    EXPECT_NE(error.find("channels there: R,G,B"), std::string::npos) << error;

    spec = AovSpec();
    spec.preset = "blender";
    EXPECT_FALSE(resolve_aovs(set, spec, buf.spec(), error));
    EXPECT_NE(error.find("unknown aov preset 'blender'"), std::string::npos) << error;
}

TEST(Aov, MissingRoleNamesRolePresetFileAndChannels)
{
    ImageBuf merged;
    std::string file = mcdn_test::test_data("box16/box_0016spp.exr");
    ASSERT_TRUE(read_inputs(merged, { { file, InputKind::Mean } }));
    AovSet set;
    std::string error;
    ASSERT_TRUE(resolve_aovs(set, AovSpec(), merged.spec(), error)) << error;
    EXPECT_FALSE(set.require({ Role::Color, Role::ColorVariance }, merged.spec(), error));
    EXPECT_NE(error.find("role 'color_variance'"), std::string::npos) << error;
    EXPECT_NE(error.find("preset 'cycles'"), std::string::npos) << error;
    EXPECT_NE(error.find("variance.ViewLayer.Combined.R"), std::string::npos) << error;
    EXPECT_NE(error.find("-i:as=variance"), std::string::npos) << error;
    EXPECT_NE(error.find("ViewLayer.Combined.A"), std::string::npos) << error;
    EXPECT_EQ(error.find('\n'), std::string::npos) << "one line";
}

TEST(Aov, RoleNamesRoundTrip)
{
    for (int r = 0; r < kRoleCount; ++r)
        EXPECT_EQ(role_from_name(role_name(Role(r))), Role(r));
    EXPECT_EQ(face_of(Role::Albedo, Face::HalfA), Role::AlbedoA);
    EXPECT_EQ(role_channel_count(Role::DepthB), 1);
    EXPECT_EQ(role_channel_count(Role::NormalVariance), 3);
}
