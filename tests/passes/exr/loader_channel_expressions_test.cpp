// The loader's `channels` parameter beyond channel names (docs/layouts.md, "The channels
// override"): constant factors that scale and flip an output (motion vectors of other
// conventions) and named presets for other renderers' AOV names.
#include <gtest/gtest.h>

#include "ExrLoader.h"
#include "exr_test_util.h"
#include "kestrel/testing/PassHarness.h"

using kestrel::exr::ExrLoader;
using kestrel::testing::PassHarness;
using namespace exrtest;

namespace {

constexpr int W = 4, H = 3;

/// One W x H frame: the given channels, each holding `value` + its pixel index.
void writeFrame(const fs::path& file, const std::map<std::string, float>& channels) {
    Channels ch;
    for (const auto& [name, value] : channels) {
        auto& v = ch[name];
        v.resize(size_t(W * H));
        for (int i = 0; i < W * H; ++i) v[size_t(i)] = value + float(i);
    }
    writeExr(file, Imath::Box2i({0, 0}, {W - 1, H - 1}), ch);
}

PassHarness loaderWith(const fs::path& dir, const std::string& channels) {
    return PassHarness::make<ExrLoader>(
        {1, 1}, {{"path", (dir / "f.####.exr").string()}, {"channels", channels}});
}

}  // namespace

TEST(ExrLoaderChannelExpressions, ConstantsScaleAndFlipPerChannel) {
    TempDir tmp("chexpr");
    writeFrame(tmp.path / "f.0001.exr", {{"R", 1}, {"G", 1}, {"B", 1}, {"mv.X", 10}, {"mv.Y", 20}});
    for (const auto& [spec, sx, sy] :
         std::vector<std::tuple<std::string, float, float>>{{"motion=mv*(1,-1)", 1.f, -1.f},
                                                            {"motion=-0.5*mv", -0.5f, -0.5f},
                                                            {"motion=mv*2*(1,-1)", 2.f, -2.f}}) {
        auto h = loaderWith(tmp.path, spec);
        RecordingResolve rc(1);
        h.pass().resolve(rc);
        h.useOutputs({"motion"});
        h.ctx.frameNumber = 1;
        h.run();
        EXPECT_EQ(h.out("motion").at(0, 2, 1), sx * (10.f + 6.f)) << spec;
        EXPECT_EQ(h.out("motion").at(1, 2, 1), sy * (20.f + 6.f)) << spec;
    }
}

TEST(ExrLoaderChannelExpressions, ConstantsThatCannotApplyAreRefusedNamingTheItem) {
    TempDir tmp("chexprbad");
    writeFrame(tmp.path / "f.0001.exr", {{"R", 1}, {"G", 1}, {"B", 1}, {"mv.X", 1}, {"mv.Y", 1}});
    for (const auto& [spec, why] : std::vector<std::pair<std::string, std::string>>{
             {"motion=mv*2+mv", "only an expression of one term"},
             {"motion=mv*(1,-1,1)", "3 values for an output of 2"},
             {"motion=mv*(1,x)", "'x' in (1,x) is not a number"},
             {"motion=-1", "constants only"},
             {"albedo=@nope", "no channel group"},
             {"@vray", "no preset '@vray' (presets: @arnold, @karma)"}}) {
        auto h = loaderWith(tmp.path, spec);
        const std::string e = resolveError(h.pass());
        EXPECT_NE(e.find(why), std::string::npos) << spec << ": " << e;
    }
}

TEST(ExrLoaderChannelExpressions, ArnoldPresetReadsArnoldsAovNames) {
    TempDir tmp("charnold");
    // An Arnold multi-layer EXR: the beauty RGBA as R,G,B,A and built-in AOVs by name; no
    // specular_albedo here, so that item of the preset leaves the output as the layout found it.
    writeFrame(tmp.path / "f.0001.exr", {{"R", 1},
                                         {"G", 1},
                                         {"B", 1},
                                         {"A", 1},
                                         {"diffuse_albedo.R", 100},
                                         {"diffuse_albedo.G", 200},
                                         {"diffuse_albedo.B", 300},
                                         {"N.X", 4},
                                         {"N.Y", 5},
                                         {"N.Z", 6},
                                         {"Z", 7},
                                         {"P.X", 8},
                                         {"P.Y", 9},
                                         {"P.Z", 10}});
    auto h = loaderWith(tmp.path, "@arnold,albedo=diffuse_albedo");
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.absent.count("normal"), 0u);
    EXPECT_EQ(rc.absent.count("depth"), 0u);
    EXPECT_EQ(rc.absent.count("diffuseAlbedo"), 0u);
    EXPECT_EQ(rc.absent.count("specularAlbedo"), 1u);
    h.useOutputs({"albedo", "diffuseAlbedo", "normal", "depth", "position"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("albedo").at(2, 1, 0), 301.f);  // the item after the preset overrides it
    EXPECT_EQ(h.out("diffuseAlbedo").at(1, 0, 1), 204.f);
    EXPECT_EQ(h.out("normal").at(2, 3, 2), 6.f + 11.f);
    EXPECT_EQ(h.out("depth").at(0, 1, 1), 7.f + 5.f);
    EXPECT_EQ(h.out("position").at(0, 0, 0), 8.f);
}

TEST(ExrLoaderChannelExpressions, KarmaPresetReadsTheBeautyC) {
    TempDir tmp("chkarma");
    writeFrame(tmp.path / "f.0001.exr", {{"C.R", 50}, {"C.G", 60}, {"C.B", 70}, {"C.A", 1}});
    auto h = loaderWith(tmp.path, "@karma");
    RecordingResolve rc(1);
    h.pass().resolve(rc);
    EXPECT_EQ(rc.absent.count("color"), 0u);
    h.useOutputs({"color"});
    h.ctx.frameNumber = 1;
    h.run();
    EXPECT_EQ(h.out("color").at(1, 3, 0), 63.f);
}
